"""Small hand-built skeletons and motions with exactly known answers."""
from __future__ import annotations

import numpy as np

from engine.mocap import Motion, Skeleton
from engine.mocap import quaternions as quat


def chain_skeleton() -> Skeleton:
    """root -> a (1 m up) -> b (0.5 m along +X from a) -> b_end (0.25 m along +X)."""
    return Skeleton(("root", "a", "b", "b_end"), np.array([-1, 0, 1, 2]),
                    np.array([[0, 0, 0], [0, 1.0, 0], [0.5, 0, 0], [0.25, 0, 0]]),
                    np.array([False, False, False, True]))


def constant_motion(skeleton: Skeleton, n_frames: int, fps: float, rotations: np.ndarray | None = None,
                    root_m: np.ndarray | None = None) -> Motion:
    rots = quat.identity((n_frames, skeleton.n_joints)) if rotations is None else rotations
    root = np.zeros((n_frames, 3)) if root_m is None else root_m
    return Motion(skeleton, fps, root, rots)


def axis_angle(axis: str, angle_rad: np.ndarray | float) -> np.ndarray:
    angle = np.asarray(angle_rad, float)
    return quat.from_euler(angle[..., None], axis)
