"""Training the hierarchical HMM: segmentation, DTW registration, per-frame joint Gaussians, flattened
transitions (spec B2.1-B2.3).

One state per registered frame of each phase template (behaviour x gait phase). The template of a phase is the
mean of its registered segments; every segment is also kept as its own chain (same length) for the reactive
interpolation. Each template frame i holds a joint Gaussian over (X, Y) estimated across the H registered
segments, ridge-regularised; only mean_X, mean_Y and the regression gain Sigma_XY Sigma_YY^-1 are needed at
runtime (the interpolated covariance sum a_k^2 Sigma is a scalar multiple of Sigma, so the gain is unchanged).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse

from engine.hmm.config import HMMConfig
from engine.hmm.dtw import dtw, medoid, register
from engine.hmm.phases import PHASES, Segment


@dataclass
class TrainingClip:
    """One clip's features at the model rate: body X (F, dx), IMU Y (F, dy), DTW features A (F, da)."""

    body: np.ndarray
    imu: np.ndarray
    align: np.ndarray
    segments: list[Segment]
    behaviour: str


@dataclass
class PhaseModel:
    behaviour: str
    phase: int
    seg_body: np.ndarray   # (H, L, dx) registered segments
    seg_imu: np.ndarray    # (H, L, dy) z-scored
    mean_body: np.ndarray  # (L, dx)
    mean_imu: np.ndarray   # (L, dy) z-scored
    gain: np.ndarray       # (L, dx, dy) Sigma_XY Sigma_YY^-1 (per z-unit of Y)

    @property
    def length(self) -> int:
        return self.mean_body.shape[0]

    @property
    def name(self) -> str:
        return f"{self.behaviour}-{PHASES[self.phase]}"


def gaussian_gain(body: np.ndarray, imu: np.ndarray, ridge: float, floor: float) -> np.ndarray:
    """Regression gain Sigma_XY (Sigma_YY + ridge diag(var) + floor I)^-1 per frame from H samples (z-scored Y).
    body (H, L, dx), imu (H, L, dy) -> (L, dx, dy); zero when H == 1 (one example has no covariance)."""
    h = body.shape[0]
    if h < 2:
        return np.zeros((body.shape[1], body.shape[2], imu.shape[2]))
    bx = body - body.mean(axis=0)
    by = imu - imu.mean(axis=0)
    cov_xy = np.einsum("hli,hlj->lij", bx, by) / (h - 1)
    cov_yy = np.einsum("hli,hlj->lij", by, by) / (h - 1)
    var = np.einsum("lii->li", cov_yy)
    cov_yy = cov_yy + (ridge * var + floor)[:, :, None] * np.eye(imu.shape[2])
    return np.linalg.solve(cov_yy, np.swapaxes(cov_xy, 1, 2)).swapaxes(1, 2)


def conditional_mean(mean_body: np.ndarray, mean_imu: np.ndarray, gain: np.ndarray, y: np.ndarray) -> np.ndarray:
    """mu_X + Sigma_XY Sigma_YY^-1 (y - mu_Y) for every state: (L, dx)."""
    return mean_body + np.einsum("lij,lj->li", gain, y - mean_imu)


def _register_phase(parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]], config: HMMConfig) -> tuple[np.ndarray, np.ndarray]:
    """DTW-register (body, imu, align) segments of one phase to the medoid reference's length."""
    candidates = parts[: config.medoid_candidates]
    ref = parts[medoid([a for _, _, a in candidates])][2]
    bodies, imus = [], []
    for body, imu, align in parts:
        _, path = dtw(align, ref)
        bodies.append(register(body, path, len(ref)))
        imus.append(register(imu, path, len(ref)))
    return np.stack(bodies), np.stack(imus)


@dataclass
class HierarchicalHMM:
    config: HMMConfig
    phases: list[PhaseModel]
    imu_mean: np.ndarray
    imu_std: np.ndarray
    transitions: sparse.csr_matrix   # (S, S) over all template frames
    offsets: np.ndarray              # (P + 1,) first state of each phase
    state_imu_z: np.ndarray          # (S, dy) z-scored template IMU means

    @property
    def fps(self) -> float:
        return self.config.fps

    @property
    def n_states(self) -> int:
        return int(self.offsets[-1])

    @property
    def training_frames(self) -> int:
        return int(sum(p.seg_body.shape[0] * p.length for p in self.phases))

    def zscore(self, y: np.ndarray) -> np.ndarray:
        return (y - self.imu_mean) / self.imu_std

    @classmethod
    def train(cls, clips: list[TrainingClip], config: HMMConfig = HMMConfig()) -> "HierarchicalHMM":
        # everything below works on z-scored IMU features, so sigma and the ridge are in comparable units
        all_imu = np.concatenate([c.imu for c in clips])
        imu_mean, imu_std = all_imu.mean(axis=0), all_imu.std(axis=0) + 1e-9
        groups: dict[tuple[str, int], list] = {}
        for clip in clips:
            imu_z = (clip.imu - imu_mean) / imu_std
            for seg in clip.segments:
                sl = slice(seg.start, seg.stop)
                groups.setdefault((clip.behaviour, seg.phase), []).append((clip.body[sl], imu_z[sl], clip.align[sl]))
        if not groups:
            raise ValueError("no gait segments found in the training clips")
        phases = []
        for (behaviour, phase), parts in sorted(groups.items()):
            body, imu = _register_phase(parts, config)
            phases.append(PhaseModel(behaviour, phase, body, imu, body.mean(axis=0), imu.mean(axis=0),
                                     gaussian_gain(body, imu, config.ridge, config.ridge_floor)))
        offsets = np.r_[0, np.cumsum([p.length for p in phases])]
        state_imu_z = np.concatenate([p.mean_imu for p in phases])
        return cls(config, phases, imu_mean, imu_std, transition_matrix(phases, offsets, config), offsets, state_imu_z)


def _next_phase(phases: list[PhaseModel], index: int) -> int:
    """The following gait phase of the same behaviour (wrapping TSW -> IC; phases a behaviour never showed are
    skipped)."""
    mine = sorted((p.phase, i) for i, p in enumerate(phases) if p.behaviour == phases[index].behaviour)
    order = [i for _, i in mine]
    return order[(order.index(index) + 1) % len(order)]


def transition_matrix(phases: list[PhaseModel], offsets: np.ndarray, config: HMMConfig) -> sparse.csr_matrix:
    """Flattened two-level transitions (Murphy & Paskin): inside a chain self/next/skip; mass that runs past the
    chain end goes 1/3 to the same phase's start, 1/3 to the next phase's start, 1/3 spread over the starts of
    the other behaviours' phases (to the next phase when there is only one behaviour)."""
    rows, cols, vals = [], [], []
    steps = ((0, config.p_self), (1, config.p_next), (2, config.p_skip))
    for h, p in enumerate(phases):
        nxt = _next_phase(phases, h)
        others = [k for k, q in enumerate(phases) if q.behaviour != p.behaviour]
        for i in range(p.length):
            src = offsets[h] + i
            end_mass = 0.0
            for step, prob in steps:
                if i + step < p.length:
                    rows.append(src); cols.append(offsets[h] + i + step); vals.append(prob)
                else:
                    end_mass += prob
            if end_mass > 0:
                targets = [(offsets[h], end_mass / 3), (offsets[nxt], end_mass / 3)]
                if others:
                    targets += [(offsets[k], end_mass / 3 / len(others)) for k in others]
                else:
                    targets.append((offsets[nxt], end_mass / 3))
                for dst, prob in targets:
                    rows.append(src); cols.append(dst); vals.append(prob)
    n = int(offsets[-1])
    return sparse.csr_matrix((vals, (rows, cols)), shape=(n, n))
