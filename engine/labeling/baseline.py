"""Closest-point tracking, the baseline paper 001 compares against.

Each label takes the point nearest to its own previous output position, so an error propagates (the paper's
point: the baseline loses tracks after its first mistake). Two variants (spec 001 §5): ``naive`` lets several
labels take the same point; ``hungarian`` makes the assignment one-to-one with scipy's linear_sum_assignment.
A label whose point is taken keeps its last position.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree


class ClosestPointTracker:
    def __init__(self, last_positions_m: np.ndarray, one_to_one: bool = True):
        self.last = np.asarray(last_positions_m, dtype=float).copy()  # (L,3); NaN = not seen yet, never tracked
        self.one_to_one = one_to_one

    def step(self, points_m: np.ndarray) -> np.ndarray:
        """(m,3) points → (L,) point index per label, −1 when none."""
        points = np.asarray(points_m, dtype=float).reshape(-1, 3)
        finite = np.flatnonzero(np.isfinite(points).all(axis=1))
        label_point = np.full(len(self.last), -1)
        known = np.flatnonzero(np.isfinite(self.last).all(axis=1))  # a NaN cost would make the solver fail
        if len(finite) == 0 or len(known) == 0:
            return label_point
        if self.one_to_one:
            cost = np.linalg.norm(self.last[known, None, :] - points[finite][None, :, :], axis=2)
            rows, cols = linear_sum_assignment(cost)
            label_point[known[rows]] = finite[cols]
        else:
            label_point[known] = finite[cKDTree(points[finite]).query(self.last[known])[1]]
        hit = label_point >= 0
        self.last[hit] = points[label_point[hit]]
        return label_point


def bootstrap_training_labels(first_m: np.ndarray, clouds: list[np.ndarray]) -> np.ndarray:
    """Label training frames 2..T from a labelled first frame by one-to-one closest point (spec 001 §2.2 step 1).

    first_m (L,3) labelled positions; clouds: the following unordered frames. Returns (1 + len(clouds), L, 3)
    with NaN for labels that got no point. Valid only while the subjects are apart and move little per frame,
    which is what the training window assumes anyway."""
    tracker = ClosestPointTracker(first_m, one_to_one=True)
    out = np.full((1 + len(clouds),) + np.shape(first_m), np.nan)
    out[0] = first_m
    for t, cloud in enumerate(clouds, start=1):
        label_point = tracker.step(cloud)
        hit = label_point >= 0
        out[t, hit] = np.asarray(cloud)[label_point[hit]]
    return out
