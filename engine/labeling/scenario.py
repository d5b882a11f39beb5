"""Turn labelled marker trajectories into an unlabelled stream with known truth, and score labelings against it.

Why: the paper's data are proprietary and its plots carry no numbers, so the labeler is validated on real
labelled mocap degraded the way optical capture degrades (spec 001 §5): Gaussian noise, occlusion gaps of up to
20 frames, ghost points, and a shuffled point order every frame. The truth is kept so accuracy, false and missed
assignments, swaps between subjects and recovery error can be counted exactly.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class DegradeConfig:
    """noise_m: per-coordinate Gaussian noise. gap_rate: gaps started per label per frame. max_gap_frames: gap
    length is uniform in 1..max_gap_frames. ghosts_per_frame: mean (Poisson) ghost points per frame, scattered
    within ghost_spread_m of a random true marker. protect_frames: leading frames kept complete (training)."""

    noise_m: float = 0.0005
    gap_rate: float = 0.003
    max_gap_frames: int = 20
    ghosts_per_frame: float = 2.0
    ghost_spread_m: float = 0.15
    protect_frames: int = 50


@dataclass
class Stream:
    """clouds[t]: (m_t,3) unordered points; truth[t]: (m_t,) true label of each point (−1 = ghost);
    clean_m: (F,L,3) noise-free truth positions; visible: (F,L) whether each label was in the cloud;
    subjects: (L,) subject id per label."""

    clouds: list[np.ndarray]
    truth: list[np.ndarray]
    clean_m: np.ndarray
    visible: np.ndarray
    subjects: np.ndarray


def degrade(positions_m: np.ndarray, subjects: np.ndarray, config: DegradeConfig, rng: np.random.Generator) -> Stream:
    """Unlabelled, shuffled, noisy, gappy, ghosted clouds from labelled positions (F,L,3) (NaN = already missing)."""
    n_frames, n_labels = positions_m.shape[:2]
    visible = ~np.isnan(positions_m).any(axis=2)
    starts = rng.random((n_frames, n_labels)) < config.gap_rate
    starts[: config.protect_frames] = False
    for t, label in zip(*np.nonzero(starts)):
        visible[t : t + int(rng.integers(1, config.max_gap_frames + 1)), label] = False
    noisy = positions_m + rng.normal(0.0, config.noise_m, positions_m.shape)
    clouds, truth = [], []
    for t in range(n_frames):
        labels = np.flatnonzero(visible[t])
        pts = noisy[t, labels]
        n_ghosts = 0 if t < config.protect_frames else int(rng.poisson(config.ghosts_per_frame))
        if n_ghosts and len(pts):
            anchors = pts[rng.integers(0, len(pts), n_ghosts)]
            pts = np.vstack([pts, anchors + rng.uniform(-config.ghost_spread_m, config.ghost_spread_m, (n_ghosts, 3))])
            labels = np.concatenate([labels, np.full(n_ghosts, -1)])
        perm = rng.permutation(len(pts))
        clouds.append(pts[perm])
        truth.append(labels[perm])
    return Stream(clouds, truth, positions_m, visible, np.asarray(subjects))


@dataclass
class Score:
    """Counts over visible labels (frames after training): correct, wrong point (false), no point (missed);
    swaps: a label given a point of another subject; recovery_err_m: errors of recovered positions."""

    correct: int = 0
    false: int = 0
    missed: int = 0
    swaps: int = 0
    recovery_err_m: list[float] = field(default_factory=list)
    recovery_rel: list[float] = field(default_factory=list)

    @property
    def total(self) -> int:
        return self.correct + self.false + self.missed

    @property
    def accuracy(self) -> float:
        return self.correct / max(self.total, 1)


def score_frame(
    score: Score,
    stream: Stream,
    t: int,
    label_point: np.ndarray,
    recovered_m: np.ndarray | None = None,
    body_extent_m: np.ndarray | None = None,
) -> None:
    """Add frame t to ``score``. label_point (L,): point index per label or −1. recovered_m (L,3): positions
    reported for labels that were not visible (NaN if none); body_extent_m (L,): largest pair distance in each
    label's rigid body, for the paper's Fig. 8 metric (error / extent)."""
    truth = stream.truth[t]
    vis = stream.visible[t]
    got = np.where(label_point >= 0, truth[np.maximum(label_point, 0)], -2)
    labels = np.arange(len(label_point))
    score.correct += int(np.sum(vis & (got == labels)))
    score.missed += int(np.sum(vis & (got == -2)))
    score.false += int(np.sum(vis & (got != labels) & (got != -2)))
    other = (got >= 0) & (stream.subjects[np.maximum(got, 0)] != stream.subjects)
    score.swaps += int(np.sum(other))
    if recovered_m is not None:
        gone = ~vis & ~np.isnan(recovered_m).any(axis=1) & ~np.isnan(stream.clean_m[t]).any(axis=1)
        err = np.linalg.norm(recovered_m[gone] - stream.clean_m[t, gone], axis=1)
        score.recovery_err_m.extend(err.tolist())
        if body_extent_m is not None:
            score.recovery_rel.extend((err / body_extent_m[gone]).tolist())


def bring_together(
    positions_m: np.ndarray, subjects: np.ndarray, mover: int, gap_m: float, start: int, ramp_frames: int
) -> np.ndarray:
    """Slide subject ``mover`` horizontally (x, y of a Z-up lab) towards the others from frame ``start`` on, over
    ``ramp_frames``, until the mean positions are ``gap_m`` apart — the spec's "apart in training, then
    together" generator applied to real recordings of people captured apart."""
    out = positions_m.copy()
    moving = subjects == mover
    offset = np.nanmean(positions_m[:, ~moving], axis=(0, 1)) - np.nanmean(positions_m[:, moving], axis=(0, 1))
    offset[2] = 0.0
    length = np.linalg.norm(offset)
    shift = offset * max(length - gap_m, 0.0) / length
    ramp = np.clip((np.arange(len(out)) - start) / max(ramp_frames, 1), 0.0, 1.0)
    out[:, moving] += ramp[:, None, None] * shift
    return out
