"""cos/sin in float32 by a fixed sequence of multiplies and adds, for numpy arrays and numba scalars alike.

The search carries each path's heading O and needs its cos/sin every step; np.cos (SIMD, SVML-like) and
numba's math.cos (libm) round differently, and the compiled step must be bit-identical to the numpy reference.
One polynomial evaluated as plain float32 arithmetic rounds the same under both (numba does not contract a*b + c
into an fma without fastmath). Half angle h = x/2 in [-pi/2, pi/2] for x in [-pi, pi]: Taylor to h^11 / h^12
(truncation < 6e-8), then sin x = 2 sin h cos h, cos x = cos^2 h - sin^2 h; error below 5e-7.

numba's on-disk cache keys the kernels by kernels_numba.py alone: after editing this file, delete
engine/graph/__pycache__/kernels_numba*.nb* (or touch kernels_numba.py), or the compiled step keeps the old polynomial.
"""
from __future__ import annotations

import numpy as np

_HALF = np.float32(0.5)
_TWO = np.float32(2.0)
_ONE = np.float32(1.0)
_S3, _S5, _S7, _S9, _S11 = (np.float32(v) for v in (-1 / 6, 1 / 120, -1 / 5040, 1 / 362880, -1 / 39916800))
_C2, _C4, _C6, _C8, _C10, _C12 = (np.float32(v) for v in (-1 / 2, 1 / 24, -1 / 720, 1 / 40320, -1 / 3628800,
                                                           1 / 479001600))


def cos_sin(x):
    """(cos x, sin x) of float32 x in [-pi, pi] (scalar or array)."""
    h = x * _HALF
    h2 = h * h
    s = h * (_ONE + h2 * (_S3 + h2 * (_S5 + h2 * (_S7 + h2 * (_S9 + h2 * _S11)))))
    c = _ONE + h2 * (_C2 + h2 * (_C4 + h2 * (_C6 + h2 * (_C8 + h2 * (_C10 + h2 * _C12)))))
    return c * c - s * s, _TWO * s * c
