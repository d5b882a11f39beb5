"""Ground-plane geometry shared by the graph builder, the search and the post-processing.

Conventions (docs/CONTRACTS.md): Y up, ground plane X-Z, heading = atan2(fwd_x, fwd_z) in radians, 0 facing +Z,
positive counter-clockwise seen from above. A heading `h` maps a local ground vector (x, z) -- forward = +Z -- to
world as `rotate_ground(v, h)`; that is a rotation about +Y by `h`.
"""
from __future__ import annotations

import numpy as np

from engine.mocap import ground

TWO_PI = 2.0 * np.pi


# One definition for the whole engine: heading differences never count a full turn as an error.
wrap_angle = ground.wrap_angle


def rotate_ground(vec_xz: np.ndarray, heading_rad: np.ndarray | float) -> np.ndarray:
    """Rotate ground-plane vectors (..., 2) = (x, z) about +Y by `heading_rad` (broadcast)."""
    vec_xz = np.asarray(vec_xz, dtype=float)
    c, s = np.cos(heading_rad), np.sin(heading_rad)
    x, z = vec_xz[..., 0], vec_xz[..., 1]
    return np.stack([x * c + z * s, -x * s + z * c], axis=-1)


def rotate_points_y(points: np.ndarray, heading_rad: float) -> np.ndarray:
    """Rotate 3-D points (..., 3) about +Y by `heading_rad` (same convention as `rotate_ground`)."""
    out = np.array(points, dtype=float, copy=True)
    out[..., [0, 2]] = rotate_ground(points[..., [0, 2]], heading_rad)
    return out

