"""The least-squares rotation between paired vectors (Wahba's problem, solved by SVD as in Kabsch).

Why one module: the marker labeler recovers a rigid body's pose from its seen markers, and the calibration
wizard rotates sensor axes onto segment axes from several poses; both are this same solve, and the reflection
guard (det = +1) is the part that is easy to get wrong in a copy."""
from __future__ import annotations

import numpy as np


def best_rotation(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Rotation matrix R (3, 3) minimising sum_i |R @ src_i - dst_i|^2 for paired rows src, dst (N, 3).

    Rows are directions or centred points; the caller removes translation. Never a reflection."""
    u, _, vt = np.linalg.svd(np.asarray(dst, float).T @ np.asarray(src, float))
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt
