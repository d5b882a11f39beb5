"""Dynamic time warping and registration of segments to a reference length (spec B2.1b)."""
from __future__ import annotations

import numpy as np


def dtw(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    """DTW between sequences a (n, d) and b (m, d), Euclidean local cost, steps (1,0), (0,1), (1,1).

    Each row of the cost table is computed at once: D[i, j] = S[j] + min_{k<=j} (A[k] - S[k]) with
    A[k] = c[i,k] + min(D[i-1,k-1], D[i-1,k]) and S the running sum of c[i, :], which is exactly the
    horizontal-step recursion. Returns (total cost, warping path (P, 2) of index pairs)."""
    cost = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    n, m = cost.shape
    table = np.empty((n, m))
    table[0] = np.cumsum(cost[0])
    for i in range(1, n):
        prev = table[i - 1]
        diag = np.r_[np.inf, prev[:-1]]
        arrive = cost[i] + np.minimum(diag, prev)
        running = np.cumsum(cost[i])
        table[i] = running + np.minimum.accumulate(arrive - running)
    i, j = n - 1, m - 1
    path = [(i, j)]
    while i > 0 or j > 0:
        options = []
        if i > 0 and j > 0:
            options.append((table[i - 1, j - 1], i - 1, j - 1))
        if i > 0:
            options.append((table[i - 1, j], i - 1, j))
        if j > 0:
            options.append((table[i, j - 1], i, j - 1))
        _, i, j = min(options)
        path.append((i, j))
    return float(table[-1, -1]), np.array(path[::-1])


def register(values: np.ndarray, path: np.ndarray, length: int) -> np.ndarray:
    """Values (n, d) of a segment brought onto the reference's `length` frames: each reference frame takes the
    mean of the segment frames the warping path maps to it (path columns: segment index, reference index)."""
    sums = np.zeros((length, values.shape[1]))
    counts = np.zeros(length)
    np.add.at(sums, path[:, 1], values[path[:, 0]])
    np.add.at(counts, path[:, 1], 1.0)
    return sums / counts[:, None]


def medoid(sequences: list[np.ndarray]) -> int:
    """Index of the sequence with the least total DTW distance to the others."""
    n = len(sequences)
    dist = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            dist[i, j] = dist[j, i] = dtw(sequences[i], sequences[j])[0]
    return int(np.argmin(dist.sum(axis=1)))
