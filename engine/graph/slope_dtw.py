"""The interpolation DTW (steps (1,1), (1,2), (2,1), forbidden inf cells) through the maintained `dtw-python`.

Why a library: `dtw-python` runs the same recursion in C and returns the identical path on every cost matrix of
the sample graph (test: tests/engine/graph/test_slope_dtw.py; speed: bench/bench_dtw.py). Its step pattern is
written in the library's own notation: each step adds only the cost of the cell it lands on (weight 1 on
``(0, 0)``, the origin ``-1``), exactly `interpolate.slope_constrained_dtw`, which stays as the reference and the
fallback when the `engine` extra is not installed."""
from __future__ import annotations

import numpy as np

try:
    import dtw as _dtw_python
except ImportError:  # the engine extra is absent: interpolate uses its numpy reference
    _dtw_python = None

HAVE_DTW_PYTHON = _dtw_python is not None
# rows: pattern id, delta i, delta j, weight (-1 marks the step's origin cell)
_STEPS = np.array([[1, 1, 1, -1], [1, 0, 0, 1], [2, 1, 2, -1], [2, 0, 0, 1], [3, 2, 1, -1], [3, 0, 0, 1]])
_PATTERN = _dtw_python.StepPattern(_STEPS, "N") if HAVE_DTW_PYTHON else None


def library_path(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Same contract as `interpolate.slope_constrained_dtw`: (rows, cols) of the cheapest path from (0, 0) to the
    last cell, or None when no path avoids the inf cells."""
    if not (np.isfinite(cost[0, 0]) and np.isfinite(cost[-1, -1])):
        return None
    try:
        alignment = _dtw_python.dtw(cost, step_pattern=_PATTERN)
    except ValueError:  # "No warping path found compatible with the local constraints"
        return None
    return np.asarray(alignment.index1), np.asarray(alignment.index2)
