"""Dynamic time warping and registration of segments to a reference length (spec B2.1b).

DTW runs in the maintained C library `dtaidistance` (the `engine` extra) when it is installed: with
``inner_dist='euclidean'`` its local cost is the Euclidean distance, as here, and on the HMM's own phase segments
it returns identical distances and paths (tests/engine/hmm/test_dtw_library.py) several times faster
(bench/bench_dtw.py). Note ``dtaidistance.dtw_ndim.warping_path_fast`` ignores ``inner_dist`` (it always uses the
squared Euclidean cost), so the path comes from ``warping_paths_fast`` + ``best_path``. The numpy recursion
(:func:`dtw_reference`) is the fallback without the extra and the reference the tests compare against."""
from __future__ import annotations

import logging

import numpy as np

try:
    from dtaidistance import dtw as _dtai
    from dtaidistance import dtw_ndim as _dtai_ndim
except ImportError:  # the engine extra is absent: the numpy reference is used
    _dtai = _dtai_ndim = None
# the library logs two INFO lines per distance computation: dozens per HMM training in the console's log
logging.getLogger("be.kuleuven.dtai.distance").setLevel(logging.WARNING)

HAVE_DTAIDISTANCE = _dtai_ndim is not None


def dtw(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    """DTW between sequences a (n, d) and b (m, d) with Euclidean local cost and steps (1,0), (0,1), (1,1):
    (total cost, warping path (P, 2)); `dtaidistance` when installed, else :func:`dtw_reference`."""
    if not HAVE_DTAIDISTANCE:
        return dtw_reference(a, b)
    total, paths = _dtai_ndim.warping_paths_fast(np.ascontiguousarray(a, float), np.ascontiguousarray(b, float),
                                                 inner_dist="euclidean")
    return float(total), np.array(_dtai.best_path(paths), dtype=int)


def dtw_reference(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
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


def distance_matrix(sequences: list[np.ndarray]) -> np.ndarray:
    """Symmetric (n, n) DTW distances (Euclidean local cost), zero diagonal."""
    n = len(sequences)
    if HAVE_DTAIDISTANCE:
        seqs = [np.ascontiguousarray(s, float) for s in sequences]
        return np.asarray(_dtai_ndim.distance_matrix_fast(seqs, inner_dist="euclidean", parallel=False), float)
    dist = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            dist[i, j] = dist[j, i] = dtw_reference(sequences[i], sequences[j])[0]
    return dist


def medoid(sequences: list[np.ndarray]) -> int:
    """Index of the sequence with the least total DTW distance to the others."""
    return int(np.argmin(distance_matrix(sequences).sum(axis=1)))
