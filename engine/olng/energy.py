"""Kernel-prior energy of Tautges et al. §5 (spec A2.6-A2.7), minimised in a weighted-PCA subspace.

E(q) = w_prior (w_pose E_pose + w_motion E_motion + w_smooth E_smooth) + w_contr E_contr, each term a weighted
sum over the I hypotheses of sqrt(|target_i - f(q)|): the square-root kernel keeps a usable gradient far from the
samples and, unlike a Gaussian/Mahalanobis prior, lets clusters of hypotheses form separate minima.

Solvers (EnergyConfig.solver): "auto" = majorise-minimise for the square-root kernels (`KernelEnergy._irls`) and
Levenberg-Marquardt for the Mahalanobis baseline; "trf" = scipy least_squares on residuals
rho_i = sqrt(omega w_i) (|r_i|^2 + eps^2)^(1/8) (sum rho^2 = omega sum w_i sqrt|r_i| up to eps), as the spec
suggests. Jacobians are forward differences over the subspace from ONE batched FK call over (1 + dims) poses.
Units inside: angles in EnergyConfig.angle_unit_rad (degrees), positions in length_unit_m (cm), time s.

With the orientation channel (issue 18) a tilt term joins them: each sensor's measured up direction in its own
axes against the one the pose gives it (FK: root tilt, bone rotation, sensor mounting), scaled by
``tilt_lever_m`` into length units, weight ``w_tilt``. It is the only term that reads a segment's lean directly:
in slow motion the control term's acceleration is gravity minus itself, i.e. nothing.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from engine.olng.config import EnergyConfig
from engine.olng.pose import Rig, fk_local, local_matrices

_UP = np.array([0.0, 1.0, 0.0])

_FD_STEP = 1e-6


def weighted_pca(samples: np.ndarray, weights: np.ndarray, kept: float, min_components: int) -> tuple[np.ndarray, np.ndarray]:
    """Local linear model of Chai & Hodgins with weights: (mean (D,), basis U (D, d)) whose d columns keep at
    least `kept` of the weighted variance (and at least min_components directions)."""
    mean = weights @ samples
    centred = samples - mean
    cov = (centred * weights[:, None]).T @ centred
    values, vectors = np.linalg.eigh(cov)
    values, vectors = values[::-1], vectors[:, ::-1]
    total = values.sum()
    if total <= 0.0:
        dims = min_components
    else:
        dims = int(np.searchsorted(np.cumsum(values) / total, kept - 1e-12) + 1)
    dims = min(max(dims, min_components), samples.shape[1])
    return mean, vectors[:, :dims]


def levenberg_marquardt(fun, fun_and_jac, z0: np.ndarray, max_iterations: int) -> np.ndarray:
    """Minimise |fun(z)|^2 by Levenberg-Marquardt on the d x d normal equations.

    WHY not scipy's trf: with ~15 unknowns and ~1000 residuals, trf's per-iteration SVD of the full Jacobian
    costs more than the whole energy; the normal equations are tiny and well conditioned with damping."""
    z = np.asarray(z0, dtype=float).copy()
    damping = 1e-3
    r, jac = fun_and_jac(z)
    cost = r @ r
    for _ in range(max_iterations):
        grad, hess = jac.T @ r, jac.T @ jac
        diag = np.diag(hess) + 1e-3 * np.diag(hess).mean() + 1e-12   # floor: flat directions stay damped
        while True:
            step = np.linalg.solve(hess + damping * np.diag(diag), -grad)
            r_new = fun(z + step)
            cost_new = r_new @ r_new
            if cost_new < cost:
                damping = max(damping / 3.0, 1e-9)
                break
            damping *= 4.0
            if damping > 1e8:
                return z
        z += step
        converged = cost - cost_new <= 1e-9 * cost or np.linalg.norm(step) <= 1e-7 * (1.0 + np.linalg.norm(z))
        r, jac = fun_and_jac(z)
        cost = r @ r
        if converged:
            break
    return z


@dataclass
class FrameProblem:
    """Targets for one output frame. Positions in energy length units (cm), (I, J*3) or (I, S*3); None = term off."""

    weights: np.ndarray                 # (I,) Eq. 1 weights
    pose_targets: np.ndarray            # (I, D) hypothesis pose vectors (rad; scaled to angle_unit_rad inside)
    motion_targets: np.ndarray | None   # (I, J*3) x^t + v dt + a dt^2 / 2
    smooth_targets: np.ndarray | None   # (I, J*3) 2x^t - x^{t-1} + a dt^2
    control_targets: np.ndarray | None  # (I, S*3) predicted sensor-tip positions
    start_pose: np.ndarray              # (D,) where the search starts (previous output or mu)
    tilt_targets: np.ndarray | None = None  # (I, S*3) measured sensor tilts (up in sensor axes) x lever (cm)


class KernelEnergy:
    """Builds residuals for a FrameProblem and minimises them over q = mu + U z."""

    def __init__(self, rig: Rig, tips: np.ndarray, config: EnergyConfig = EnergyConfig(),
                 sensor_frames: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """``sensor_frames`` = (bone (S,), local_rot (S, 3, 3)) of the worn sensors: needed for the tilt term."""
        if config.kernel not in {"sqrt", "mahalanobis"}:
            raise ValueError(f"unknown kernel {config.kernel!r}: use 'sqrt' or 'mahalanobis'")
        if config.solver not in {"auto", "trf"}:
            raise ValueError(f"unknown solver {config.solver!r}: use 'auto' or 'trf'")
        self.rig = rig
        self.tips = np.asarray(tips)
        self.sensor_frames = sensor_frames
        self.config = config
        self.last_dims = 0

    def _blocks(self, problem: FrameProblem) -> list[tuple[str, float, np.ndarray]]:
        c = self.config
        blocks = [("pose", c.w_prior * c.w_pose, problem.pose_targets / c.angle_unit_rad)]
        if problem.motion_targets is not None:
            blocks.append(("motion", c.w_prior * c.w_motion, problem.motion_targets))
        if problem.smooth_targets is not None:
            blocks.append(("smooth", c.w_prior * c.w_smooth, problem.smooth_targets))
        if problem.control_targets is not None:
            blocks.append(("control", c.w_control, problem.control_targets))
        if problem.tilt_targets is not None:
            blocks.append(("tilt", c.w_tilt, problem.tilt_targets))
        return [b for b in blocks if b[1] > 0.0]   # a zero weight switches a term off

    def features(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Batched f(q) for each term: pose vector itself, all joint positions (cm), sensor-tip positions (cm)."""
        local = local_matrices(self.rig, q)
        pos, rot = fk_local(self.rig, local)
        out = {"pose": q / self.config.angle_unit_rad}
        if self.sensor_frames is not None:
            bone, local_rot = self.sensor_frames
            root_tilt = local[:, 0]                                                    # (B, 3, 3) world <- root
            up_root = np.einsum("bji,j->bi", root_tilt, _UP)                           # up in the root frame
            up = np.einsum("sji,bskj,bk->bsi", local_rot, rot[:, bone], up_root)       # up in each sensor's axes
            out["tilt"] = up.reshape(len(q), -1) * (self.config.tilt_lever_m / self.config.length_unit_m)
        pos = pos / self.config.length_unit_m
        flat = pos.reshape(len(q), -1)
        out.update(motion=flat, smooth=flat, control=pos[:, self.tips].reshape(len(q), -1))
        return out

    def _residual_fn(self, problem: FrameProblem):
        blocks = self._blocks(problem)
        eps2 = self.config.epsilon**2
        w = problem.weights
        if self.config.kernel == "sqrt":
            # |t - f|^2 = |t-c|^2 - 2 (f-c).(t-c) + |f-c|^2 with c the weighted target mean: one GEMM per block
            # instead of a (batch, I, dims) difference tensor; centring keeps the cancellation error tiny.
            prepared = []
            for name, omega, targets in blocks:
                centre = w @ targets
                centred = targets - centre
                prepared.append((name, np.sqrt(omega * w), centre, centred, (centred**2).sum(axis=1)))

            def residuals(q: np.ndarray) -> np.ndarray:
                feats = self.features(q)
                out = []
                for name, scale, centre, centred, tt in prepared:
                    f = feats[name] - centre
                    sq = np.maximum(tt[None] - 2.0 * f @ centred.T + (f**2).sum(axis=1)[:, None], 0.0)
                    out.append(scale * (sq + eps2) ** 0.125)
                return np.concatenate(out, axis=1)

            return residuals
        # Fig. 11(b) baseline: Mahalanobis distance to the weighted Gaussian of each term's targets
        whiteners = []
        for _, omega, targets in blocks:
            mean = w @ targets
            centred = targets - mean
            cov = (centred * w[:, None]).T @ centred
            cov += (1e-2 * np.trace(cov) / len(cov) + 1e-6) * np.eye(len(cov))
            whiteners.append((mean, np.sqrt(omega) * np.linalg.cholesky(np.linalg.inv(cov)).T))

        def residuals(q: np.ndarray) -> np.ndarray:
            feats = self.features(q)
            return np.concatenate(
                [(feats[name] - mean) @ whiten.T for (name, _, _), (mean, whiten) in zip(blocks, whiteners)], axis=1
            )

        return residuals

    def solve(self, problem: FrameProblem, max_iterations: int | None = None) -> np.ndarray:
        """argmin_q E(q) in the weighted-PCA subspace of the hypotheses; returns the pose vector (D,).
        ``max_iterations``: this frame's majorise-minimise budget instead of the configured one (a live engine
        short of time, `engine.olng.keep_up`); the other solvers keep theirs."""
        mean, basis = weighted_pca(problem.pose_targets, problem.weights, self.config.variance_kept, self.config.min_components)
        self.last_dims = basis.shape[1]
        residuals = self._residual_fn(problem)

        def fun(z: np.ndarray) -> np.ndarray:
            return residuals((mean + basis @ z)[None])[0]

        def fun_and_jac(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            q0 = mean + basis @ z
            res = residuals(np.vstack([q0, q0 + _FD_STEP * basis.T]))
            return res[0], ((res[1:] - res[0]) / _FD_STEP).T

        z0 = basis.T @ (problem.start_pose - mean)
        if self.config.solver == "trf":
            z = least_squares(fun, z0, jac=lambda z: fun_and_jac(z)[1], method="trf", max_nfev=self.config.max_nfev).x
        elif self.config.kernel == "sqrt":
            z = self._irls(problem, mean, basis, z0, max_iterations)
        else:
            z = levenberg_marquardt(fun, fun_and_jac, z0, self.config.max_iterations)
        return mean + basis @ z

    def _kernel_energy(self, blocks, weights: np.ndarray, feats: dict[str, np.ndarray]) -> float:
        eps2 = self.config.epsilon**2
        return sum(omega * float(weights @ (((targets - feats[name][0]) ** 2).sum(axis=1) + eps2) ** 0.25)
                   for name, omega, targets in blocks)

    def _irls(self, problem: FrameProblem, mean: np.ndarray, basis: np.ndarray, z0: np.ndarray,
              max_iterations: int | None = None) -> np.ndarray:
        """Majorise-minimise for the square-root kernels.

        (s + eps^2)^(1/4) is concave in s = |r|^2, so around the current pose it lies below its tangent
        c_i s_i with c_i = w_i / 4 (s_i + eps^2)^(-3/4): a weighted least-squares problem, and a weighted sum of
        squares to I targets equals C |f - t_bar|^2 + const (C = sum c_i, t_bar the c-weighted target mean).
        So each iteration is ONE Gauss-Newton step on a few hundred residuals, with a backtracking check on
        the true energy; it converges in far fewer iterations than Gauss-Newton on rho = |r|^(1/4)."""
        blocks = self._blocks(problem)
        w = problem.weights
        eps2 = self.config.epsilon**2
        iterations = self.config.max_iterations if max_iterations is None else max_iterations

        def probe(z: np.ndarray, with_jacobian: bool) -> dict[str, np.ndarray]:
            q = mean + basis @ z
            return self.features(np.vstack([q, q + _FD_STEP * basis.T]) if with_jacobian else q[None])

        z = z0.copy()
        feats = probe(z, True)
        energy = self._kernel_energy(blocks, w, feats)
        for iteration in range(iterations):
            res, jac = [], []
            for name, omega, targets in blocks:
                f0 = feats[name][0]
                c = omega * w * 0.25 * (((targets - f0) ** 2).sum(axis=1) + eps2) ** -0.75
                total = c.sum()
                root = np.sqrt(total)
                res.append(root * (f0 - c @ targets / total))
                jac.append(root * (feats[name][1:] - f0).T / _FD_STEP)
            r, j = np.concatenate(res), np.vstack(jac)
            hess = j.T @ j
            step = np.linalg.solve(hess + 1e-6 * (np.diag(np.diag(hess)) + np.trace(hess) / len(hess) * np.eye(len(hess))), -(j.T @ r))
            # the first trial also brings the next iteration's Jacobian (it is usually accepted); the last
            # iteration and the backtracking trials need only the energy
            for trial in range(8):
                new_feats = probe(z + step, trial == 0 and iteration + 1 < iterations)
                new_energy = self._kernel_energy(blocks, w, new_feats)
                if new_energy < energy:
                    break
                step = 0.5 * step
            else:
                break
            z = z + step
            if energy - new_energy <= 1e-6 * energy or iteration + 1 == iterations:
                break
            if len(new_feats["pose"]) == 1:
                new_feats = probe(z, True)
            feats, energy = new_feats, new_energy
        return z
