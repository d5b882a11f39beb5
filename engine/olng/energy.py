"""Kernel-prior energy of Tautges et al. §5 (spec A2.6-A2.7), minimised in a weighted-PCA subspace.

E(q) = w_prior (w_pose E_pose + w_motion E_motion + w_smooth E_smooth) + w_contr E_contr, each term a weighted
sum over the I hypotheses of sqrt(|target_i - f(q)|): the square-root kernel keeps a usable gradient far from the
samples and, unlike a Gaussian/Mahalanobis prior, lets clusters of hypotheses form separate minima.

Solved with scipy's trust-region-reflective least squares on residuals rho_i = sqrt(omega w_i) (|r_i|^2 + eps^2)^(1/8)
(sum rho^2 = omega sum w_i sqrt|r_i| up to eps). The Jacobian is a forward difference over the subspace, computed
with ONE batched FK call over (1 + dims) poses; that keeps a frame at a few milliseconds.
Units inside: angles rad, positions cm (EnergyConfig.length_unit_m), time s.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from engine.olng.config import EnergyConfig
from engine.olng.pose import Rig, fk_root_frame

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


@dataclass
class FrameProblem:
    """Targets for one output frame. Positions in energy length units (cm), (I, J*3) or (I, S*3); None = term off."""

    weights: np.ndarray                 # (I,) Eq. 1 weights
    pose_targets: np.ndarray            # (I, D) hypothesis poses (rad)
    motion_targets: np.ndarray | None   # (I, J*3) x^t + v dt + a dt^2 / 2
    smooth_targets: np.ndarray | None   # (I, J*3) 2x^t - x^{t-1} + a dt^2
    control_targets: np.ndarray | None  # (I, S*3) predicted sensor-tip positions
    start_pose: np.ndarray              # (D,) where the search starts (previous output or mu)


class KernelEnergy:
    """Builds residuals for a FrameProblem and minimises them over q = mu + U z."""

    def __init__(self, rig: Rig, tips: np.ndarray, config: EnergyConfig = EnergyConfig()) -> None:
        if config.kernel not in {"sqrt", "mahalanobis"}:
            raise ValueError(f"unknown kernel {config.kernel!r}: use 'sqrt' or 'mahalanobis'")
        self.rig = rig
        self.tips = np.asarray(tips)
        self.config = config
        self.last_terms: dict[str, float] = {}
        self.last_dims = 0

    def _blocks(self, problem: FrameProblem) -> list[tuple[str, float, np.ndarray]]:
        c = self.config
        blocks = [("pose", c.w_prior * c.w_pose, problem.pose_targets)]
        if problem.motion_targets is not None:
            blocks.append(("motion", c.w_prior * c.w_motion, problem.motion_targets))
        if problem.smooth_targets is not None:
            blocks.append(("smooth", c.w_prior * c.w_smooth, problem.smooth_targets))
        if problem.control_targets is not None:
            blocks.append(("control", c.w_control, problem.control_targets))
        return blocks

    def features(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Batched f(q) for each term: pose vector itself, all joint positions (cm), sensor-tip positions (cm)."""
        pos, _ = fk_root_frame(self.rig, q)
        pos = pos / self.config.length_unit_m
        flat = pos.reshape(len(q), -1)
        return {"pose": q, "motion": flat, "smooth": flat, "control": pos[:, self.tips].reshape(len(q), -1)}

    def _residual_fn(self, problem: FrameProblem):
        blocks = self._blocks(problem)
        eps2 = self.config.epsilon**2
        w = problem.weights
        if self.config.kernel == "sqrt":
            scales = [np.sqrt(omega * w) for _, omega, _ in blocks]

            def residuals(q: np.ndarray) -> np.ndarray:
                feats = self.features(q)
                out = []
                for (name, _, targets), scale in zip(blocks, scales):
                    diff = targets[None] - feats[name][:, None, :]
                    out.append(scale * (np.einsum("bik,bik->bi", diff, diff) + eps2) ** 0.125)
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

    def solve(self, problem: FrameProblem) -> np.ndarray:
        """argmin_q E(q) in the weighted-PCA subspace of the hypotheses; returns the pose vector (D,)."""
        mean, basis = weighted_pca(problem.pose_targets, problem.weights, self.config.variance_kept, self.config.min_components)
        self.last_dims = basis.shape[1]
        residuals = self._residual_fn(problem)

        def fun(z: np.ndarray) -> np.ndarray:
            return residuals((mean + basis @ z)[None])[0]

        def jac(z: np.ndarray) -> np.ndarray:
            q0 = mean + basis @ z
            batch = np.vstack([q0, q0 + _FD_STEP * basis.T])
            res = residuals(batch)
            return ((res[1:] - res[0]) / _FD_STEP).T

        z0 = basis.T @ (problem.start_pose - mean)
        result = least_squares(fun, z0, jac=jac, method="trf", max_nfev=self.config.max_nfev)
        q = mean + basis @ result.x
        self.last_terms = self.term_values(problem, q)
        return q

    def term_values(self, problem: FrameProblem, q: np.ndarray) -> dict[str, float]:
        """Each term's unweighted kernel energy sum_i w_i sqrt|r_i| at q (for logging the balance, spec A2.8)."""
        feats = self.features(q[None])
        return {
            name: float(problem.weights @ np.sqrt(np.linalg.norm(targets - feats[name][0], axis=1)))
            for name, _, targets in self._blocks(problem)
        }
