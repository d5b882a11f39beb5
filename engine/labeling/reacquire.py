"""Re-acquire a rigid body's missing markers from the unlabelled points by its shape (issue 14).

Why: paper 001 only offers a label the points inside its Kalman gate. Once a whole body (or most of it) has been
missing for a while, its filters coast or follow a wrong recovery, the gate sits in the wrong place, and the body
is predicted forever: on the long CMU takes accuracy fell from 0.8 in the first 10 s to 0.1 in the last. The
shape of the body (its learned pair distances D, with spread A) does not depend on where the filters think it
is, so a body can be found again among the points no other body took:

* with ≥ 2 of its markers still labelled, every missing marker takes the leftover point whose distances to
  them best match D (distance shells intersect in a small region, so ghosts rarely fit);
* with 1 labelled marker, each leftover point that fits the distance to it is tried as a second anchor;
* with none, every pair of leftover points whose distance matches the body's most distinctive pair is tried.

Each seed is completed greedily (best-supported point first) and scored by Eq. 5; the best seed wins. A point is
kept only if its mean link term with the body's other markers is ≥ ``min_support``, and a body found from
fewer than two anchors must end with ≥ 3 markers, because two points match some pair distance by chance.
"""
from __future__ import annotations

import numpy as np


def link_terms(dist: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """Eq. 5 link term exp(−(d − D)²/(2A²)), 0 where anything is NaN (unknown model or missing point)."""
    with np.errstate(invalid="ignore"):
        z = (dist - mean) / std
        return np.nan_to_num(np.exp(-0.5 * z * z), nan=0.0)


def _complete(points: np.ndarray, seed: np.ndarray, pos: np.ndarray, mean: np.ndarray, std: np.ndarray,
              min_support: float) -> tuple[np.ndarray, float]:
    """Greedily give the body's empty markers leftover points that fit its present ones; return (assign, score).

    seed (n,): leftover point index already given to a marker, −1 otherwise; pos (n,3): positions of the present
    markers (labelled or seeded), NaN for empty ones. Score: Eq. 5 over all n(n−1)/2 links of the result."""
    n = len(seed)
    assign, pos = seed.copy(), pos.copy()
    free = np.ones(len(points), bool)
    free[assign[assign >= 0]] = False
    while True:
        present = np.flatnonzero(~np.isnan(pos).any(axis=1))
        empty = np.flatnonzero(np.isnan(pos).any(axis=1))
        cand = np.flatnonzero(free)
        if len(empty) == 0 or len(cand) == 0 or len(present) == 0:
            break
        d = np.linalg.norm(points[cand][:, None] - pos[present][None], axis=-1)[None]  # (1, P, present)
        terms = link_terms(d, mean[np.ix_(empty, present)][:, None, :], std[np.ix_(empty, present)][:, None, :])
        support = terms.mean(axis=2)  # (empty, P)
        best = np.unravel_index(int(np.argmax(support)), support.shape)
        if support[best] < min_support:
            break
        m, p = empty[best[0]], cand[best[1]]
        assign[m], pos[m], free[p] = p, points[p], False
    present = np.flatnonzero(~np.isnan(pos).any(axis=1))
    if len(present) < 2:
        return assign, 0.0
    d = np.linalg.norm(pos[present][:, None] - pos[present][None], axis=-1)
    terms = link_terms(d, mean[np.ix_(present, present)], std[np.ix_(present, present)])
    return assign, float(np.triu(terms, 1).sum() / (n * (n - 1) / 2))


def reacquire_body(
    points: np.ndarray,
    body_pos: np.ndarray,
    mean: np.ndarray,
    std: np.ndarray,
    min_support: float = 0.5,
    max_seeds: int = 64,
) -> np.ndarray:
    """Indices into ``points`` (leftover, unlabelled) for the body's unlabelled markers, −1 where none fits.

    body_pos (n,3): positions of the body's labelled markers this frame, NaN for its unlabelled ones.
    mean/std (n,n): the body's structure model D and A (A already floored). Labelled markers are never changed:
    the result is −1 for them."""
    n = len(body_pos)
    result = np.full(n, -1)
    labelled = ~np.isnan(body_pos).any(axis=1)
    if len(points) == 0 or labelled.all() or n < 3:
        return result
    known = np.isfinite(mean)
    seeds: list[np.ndarray] = []  # partial assignments: leftover point per marker, −1 none
    base = np.full(n, -1)
    fixed = np.flatnonzero(labelled)
    if len(fixed) >= 2:
        seeds.append(base)
    elif len(fixed) == 1:
        a = fixed[0]
        d = np.linalg.norm(points - body_pos[a], axis=1)
        terms = link_terms(d[None, :], mean[~labelled, a][:, None], std[~labelled, a][:, None])  # (missing, P)
        rows, cols = np.nonzero(terms >= min_support)
        order = np.argsort(-terms[rows, cols])[:max_seeds]
        for m, p in zip(np.flatnonzero(~labelled)[rows[order]], cols[order]):
            seed = base.copy()
            seed[m] = p
            seeds.append(seed)
    else:
        dist_pp = np.linalg.norm(points[:, None] - points[None], axis=-1)
        pairs = np.argwhere(np.triu(known, 1))
        # most distinctive body pairs first: long and steady links are the least likely to match by chance
        ratio = mean[pairs[:, 0], pairs[:, 1]] / std[pairs[:, 0], pairs[:, 1]]
        for i, j in pairs[np.argsort(-ratio)][:3]:
            terms = link_terms(dist_pp, mean[i, j], std[i, j])
            np.fill_diagonal(terms, 0.0)
            ps, qs = np.nonzero(terms >= min_support)
            order = np.argsort(-terms[ps, qs])[: max_seeds // 3]
            for p, q in zip(ps[order], qs[order]):
                seed = base.copy()
                seed[i], seed[j] = p, q
                seeds.append(seed)
    best, best_score = None, 0.0
    for seed in seeds:
        pos = np.where(labelled[:, None], body_pos, np.nan)
        pos[seed >= 0] = points[seed[seed >= 0]]
        done, score = _complete(points, np.maximum(seed, -1), pos, mean, std, min_support)
        if score > best_score:
            best, best_score = done, score
    if best is None:
        return result
    new = np.flatnonzero(best >= 0)
    if len(fixed) < 2 and len(fixed) + len(new) < 3:
        return result
    # every kept point must fit the body's other markers (labelled ones and the other re-acquired ones)
    pos = np.where(labelled[:, None], body_pos, np.nan)
    pos[new] = points[best[new]]
    present = np.flatnonzero(~np.isnan(pos).any(axis=1))
    d = np.linalg.norm(pos[new][:, None] - pos[present][None], axis=-1)
    terms = link_terms(d, mean[np.ix_(new, present)], std[np.ix_(new, present)])
    others = present[None, :] != new[:, None]
    support = (terms * others).sum(axis=1) / np.maximum(others.sum(axis=1), 1)
    keep = new[support >= min_support]
    result[keep] = best[keep]
    return result
