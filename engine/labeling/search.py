"""Rigid-body fitting score (paper 001 Eq. 5) and its exhaustive search over candidate assignments.

Why a table: the score is a sum over links (i, j) of a term that depends only on the options chosen for i and j.
So all link terms for all option pairs are computed once as a (n, K+1, n, K+1) table, and every assignment in the
Cartesian product ∏(cand_i ∪ {∅}) is scored by one fancy-index gather and a sum. Within-body double use of a
point is a −∞ table entry, so such assignments can never win. The enumeration index arrays are cached by the
tuple of option counts (the same few shapes recur every frame).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

_FORBIDDEN = -1e9  # score of a link that uses one observed point for two labels


@lru_cache(maxsize=4096)
def _enumeration(counts: tuple[int, ...], k: int) -> tuple[np.ndarray, np.ndarray]:
    """Every assignment for these option counts, and where its link terms sit in the flattened link table.

    Returns combos (C, n) option slots — the last option of each marker maps to the missing slot ``k`` — and
    flat (C, n_links) indices into table.reshape(−1) for the unordered links i < j."""
    n = len(counts)
    idx = np.indices(counts).reshape(n, -1).T
    combos = np.where(idx == np.asarray(counts) - 1, k, idx)
    li, lj = np.triu_indices(n, 1)
    width = k + 1
    flat = ((li * width + combos[:, li]) * n + lj) * width + combos[:, lj]
    combos.setflags(write=False)
    flat.setflags(write=False)
    return combos, flat


def link_table(option_pos: np.ndarray, option_pid: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """Eq. 5 link terms exp(−(D − D')²/(2A²)) for every pair of options, (n, K+1, n, K+1).

    option_pos (n, K+1, 3) metres, NaN for absent options (incl. the missing slot); option_pid (n, K+1), −1 absent.
    A missing option contributes 0 (the paper's BIG constant taken to its limit). NaN model entries contribute 0."""
    n, width = option_pid.shape
    flat_pos = option_pos.reshape(-1, 3)
    diff = flat_pos[:, None, :] - flat_pos[None, :, :]
    dist = np.sqrt(np.einsum("abk,abk->ab", diff, diff)).reshape(n, width, n, width)
    z = (dist - mean[:, None, :, None]) / std[:, None, :, None]
    table = np.exp(-0.5 * z * z)
    table[np.isnan(table)] = 0.0
    pid = option_pid.reshape(-1)
    clash = (pid[:, None] == pid[None, :]) & (pid[:, None] >= 0)
    table.reshape(n * width, n * width)[clash] = _FORBIDDEN
    return table


def search_body(
    cand_pid: np.ndarray,
    cand_pos: np.ndarray,
    mean: np.ndarray,
    std: np.ndarray,
    max_combinations: int,
    unary: tuple[np.ndarray, float] | None = None,
) -> tuple[np.ndarray, float, int]:
    """Best assignment of one rigid body by exhaustive search over ∏(cand_i ∪ {∅}).

    cand_pid (n, K): candidate point ids per marker, nearest first, −1 padded (valid entries first).
    cand_pos (n, K, 3): their positions. mean/std (n, n): the body's current D and A.
    unary: optional (terms (n, K), weight): per-candidate terms beyond the body's own links (labeler: links to
        neighbouring bodies across a joint, and agreement with the Kalman prediction) and their total weight;
        they join the Eq. 5 sum and its normalisation, so the score stays in [0, 1] and a body identical in shape
        to another one (left and right hand) is told apart by where it sits.
    Returns (assigned point id per marker or −1, score in [0, 1], number of assignments evaluated)."""
    n, k = cand_pid.shape
    valid = (cand_pid >= 0).sum(axis=1)
    while np.prod(valid + 1) > max_combinations:  # drop the farthest candidate of the busiest marker
        valid[np.argmax(valid)] -= 1
    keep = np.arange(k)[None, :] < valid[:, None]
    option_pid = np.full((n, k + 1), -1)
    option_pid[:, :k] = np.where(keep, cand_pid, -1)
    combos, flat = _enumeration(tuple((valid + 1).tolist()), k)
    extra, n_extra = (None, 0) if unary is None else unary
    if n < 2 and not n_extra:
        return option_pid[np.arange(n), combos[0]], 0.0, len(combos)
    option_pos = np.full((n, k + 1, 3), np.nan)
    option_pos[:, :k] = np.where(keep[..., None], cand_pos, np.nan)
    with np.errstate(invalid="ignore"):
        table = link_table(option_pos, option_pid, mean, std)
    scores = table.reshape(-1)[flat].sum(axis=1)
    if n_extra:
        options = np.zeros((n, k + 1))
        options[:, :k] = np.where(keep, extra, 0.0)
        scores = scores + options[np.arange(n), combos].sum(axis=1)
    scores = scores / (flat.shape[1] + n_extra)
    best = int(np.argmax(scores))
    return option_pid[np.arange(n), combos[best]], float(scores[best]), len(combos)
