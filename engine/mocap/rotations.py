"""Rotations fitted to directions: the smallest rotation between two directions, and the least-squares rotation
between paired vectors (Wahba's problem, solved by SVD as in Kabsch).

Why one module: the rest-pose rebasing, the calibration wizard and the marker labeler all need these, and the
degenerate cases (antiparallel directions, the det = +1 reflection guard) are what goes wrong in a copy."""
from __future__ import annotations

import numpy as np


def best_rotation(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Rotation matrix R (3, 3) minimising sum_i |R @ src_i - dst_i|^2 for paired rows src, dst (N, 3).

    Rows are directions or centred points; the caller removes translation. Never a reflection."""
    u, _, vt = np.linalg.svd(np.asarray(dst, float).T @ np.asarray(src, float))
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def _unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def minimal_rotation(from_dir: np.ndarray, to_dir: np.ndarray) -> np.ndarray:
    """Smallest rotation (3, 3) taking direction ``from_dir`` onto ``to_dir`` (Rodrigues); 180 degrees about a
    perpendicular axis when they are opposite."""
    a, b = _unit(from_dir), _unit(to_dir)
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(a @ b)
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        perp = _unit(np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0]))
        return 2.0 * np.outer(perp, perp) - np.eye(3)
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx
