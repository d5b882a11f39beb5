"""The structure model of paper 001: rigid-body clustering and sliding-window pair-distance statistics.

Clustering (spec §2.2 step 3): complete-linkage on the pair-distance std matrix A guarantees that every pair in a
group stays within the threshold. Groups larger than max_body are re-clustered at a smaller threshold; groups
smaller than min_body join the group with the smallest complete-linkage distance (a lone marker has no links and
cannot be scored).

Window (spec §2.3.5, Eqs. 1-2): D and A over the last T frames in which *both* markers of a pair were truly
observed. Running sums (Σd, Σd², count) with a ring buffer make the per-frame update O(pairs), not O(T·pairs).
"""
from __future__ import annotations

import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.spatial.distance import squareform


def pair_distances(pos: np.ndarray) -> np.ndarray:
    """(..., n, 3) → (..., n, n) Euclidean distances (NaN where a marker is missing)."""
    diff = pos[..., :, None, :] - pos[..., None, :, :]
    return np.sqrt(np.einsum("...k,...k->...", diff, diff))


def _complete_linkage_groups(std: np.ndarray, members: np.ndarray, tau: float) -> list[np.ndarray]:
    if len(members) == 1:
        return [members]
    sub = std[np.ix_(members, members)]
    tree = linkage(squareform(sub, checks=False), method="complete")
    ids = fcluster(tree, t=tau, criterion="distance")
    return [members[ids == k] for k in np.unique(ids)]


def choose_cluster_tau(std: np.ndarray, taus: np.ndarray, min_body: int = 3, max_body: int = 8) -> float:
    """The threshold (from ``taus``) that puts the most markers into groups of min_body..max_body (ties: the
    smallest). Why: skin markers are never exactly rigid, and how far from rigid depends on the training motion,
    so one fixed τ_A yields either all singletons or one blob (spec §2.2: search for τ_A)."""
    std = _finite(std)
    best_tau, best_count = float(taus[0]), -1
    for tau in taus:
        groups = _complete_linkage_groups(std, np.arange(len(std)), float(tau))
        count = sum(len(g) for g in groups if min_body <= len(g) <= max_body)
        if count > best_count:
            best_tau, best_count = float(tau), count
    return best_tau


def _finite(std: np.ndarray) -> np.ndarray:
    std = np.where(np.isfinite(std), std, 1e9)  # 1e9 m is "never rigid"; linkage rejects inf
    np.fill_diagonal(std, 0.0)
    return std


def cluster_rigid_bodies(std: np.ndarray, tau: float, min_body: int = 3, max_body: int = 8) -> list[np.ndarray]:
    """Partition markers 0..n−1 into disjoint rigid bodies from their pair-distance std matrix (n,n).

    Returns a list of sorted index arrays, ordered by first member. Needs n >= min_body. A small group merged
    into a full one may push it past max_body: a marker must belong to some body to be scored at all."""
    n = len(std)
    if n < min_body:
        raise ValueError(f"a subject needs at least {min_body} markers to form a rigid body, got {n}")
    std = _finite(std)
    groups = _complete_linkage_groups(std, np.arange(n), tau)
    split: list[np.ndarray] = []
    while groups:
        g = groups.pop()
        if len(g) <= max_body:
            split.append(g)
            continue
        sub_tau = np.max(std[np.ix_(g, g)]) * 0.999  # just below this group's own diameter
        parts = _complete_linkage_groups(std, g, min(tau, sub_tau))
        if len(parts) == 1:  # all pairs equally rigid (e.g. exactly 0): any split is as good as another
            parts = np.array_split(g, -(-len(g) // max_body))
        groups.extend(parts)
    small = sorted((g for g in split if len(g) < min_body), key=len)
    bodies = [g for g in split if len(g) >= min_body]
    for g in small:
        if not bodies:
            bodies.append(g)
            continue
        link = [np.max(std[np.ix_(g, b)]) for b in bodies]
        target = int(np.argmin(link))
        bodies[target] = np.sort(np.concatenate([bodies[target], g]))
    return sorted((np.sort(b) for b in bodies), key=lambda b: int(b[0]))


class DistanceWindow:
    """Sliding-window mean/std of intra-body pair distances, padded to (B, n_max, n_max).

    Only pairs where both markers were observed enter (recovered positions would feed the model its own guess)."""

    def __init__(self, n_bodies: int, n_max: int, length: int, sigma_min: float):
        shape = (n_bodies, n_max, n_max)
        self.length = length
        self.sigma_min = sigma_min
        self._ring = np.full((length,) + shape, np.nan)
        self._head = 0
        self._sum = np.zeros(shape)
        self._sumsq = np.zeros(shape)
        self._count = np.zeros(shape)
        self._held_mean = np.full(shape, np.nan)
        self._held_std = np.full(shape, np.nan)

    def push(self, dist: np.ndarray) -> None:
        """Add one frame's distances (B, n_max, n_max), NaN for pairs not both observed; drop the oldest."""
        old = self._ring[self._head]
        old_ok = ~np.isnan(old)
        self._sum -= np.where(old_ok, old, 0.0)
        self._sumsq -= np.where(old_ok, old * old, 0.0)
        self._count -= old_ok
        new_ok = ~np.isnan(dist)
        self._sum += np.where(new_ok, dist, 0.0)
        self._sumsq += np.where(new_ok, dist * dist, 0.0)
        self._count += new_ok
        self._ring[self._head] = dist
        self._head = (self._head + 1) % self.length

    def stats(self) -> tuple[np.ndarray, np.ndarray]:
        """(D, A): window mean and std (population, as np.std), A floored at sigma_min; NaN for never-seen pairs.

        A pair absent from the whole window keeps the statistics it had when last seen: a body hidden for longer
        than the window must still have a shape to be found again by (reacquire.py)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = self._sum / self._count
            var = np.maximum(self._sumsq / self._count - mean * mean, 0.0)
        seen = self._count > 0
        self._held_mean[seen] = mean[seen]
        self._held_std[seen] = np.maximum(np.sqrt(var[seen]), self.sigma_min)
        return self._held_mean.copy(), self._held_std.copy()
