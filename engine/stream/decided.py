"""The decided pose: what an engine emits and every sink reads (issue 29).

A pose is the root position and the local joint rotations of the engine's skeleton; joint positions are derived
from them by forward kinematics, never computed on a side path. Why: the console drew one pose (blended and
posed positions), the BVH file another (rotation blend, no posing) and the live streams a third, so what a user
exported was not what the engine knew. With one pose, the BVH written from the rotations gives back the saved
joint positions (a test checks 1 mm), live and offline.

`decided_pose` builds an `EnginePose` from rotations; `poses_to_motion` turns a run of decided poses into the
`engine.mocap.Motion` that the BVH file and the BVH / VMC streams write."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from engine.mocap import Motion, Skeleton, forward_kinematics

from .engines import EnginePose


def joint_positions(skeleton: Skeleton, root_m: np.ndarray, local_rotations: np.ndarray) -> np.ndarray:
    """(..., J, 3) world joint positions m of poses given as root (..., 3) m and local rotations (..., J, 4)."""
    root = np.asarray(root_m, float)
    rots = np.asarray(local_rotations, float)
    lead = rots.shape[:-2]
    flat = Motion(skeleton, 1.0, root.reshape(-1, 3), rots.reshape(-1, *rots.shape[-2:]))
    return forward_kinematics(flat)[0].reshape(*lead, -1, 3)


def decided_pose(skeleton: Skeleton, t: int, root_m: np.ndarray, local_rotations: np.ndarray,
                 confidence: float | None = None) -> EnginePose:
    """The `EnginePose` of push index ``t`` whose joints are the forward kinematics of the rotations."""
    root = np.asarray(root_m, float)
    rots = np.asarray(local_rotations, float)
    return EnginePose(t, joint_positions(skeleton, root, rots), confidence, root, rots)


def has_rotations(poses: Sequence[Any]) -> bool:
    """True when every pose carries its rotations (a BVH can be written from them)."""
    return bool(poses) and all(getattr(p, "local_rotations", None) is not None for p in poses)


def poses_to_motion(skeleton: Skeleton, fps: float, poses: Sequence[Any], name: str = "synthesised") -> Motion:
    """The `Motion` of decided poses (anything with ``root_m`` and ``local_rotations``: `EnginePose`,
    `engine.graph.online.EmittedPose`, `engine.stream.session.FramePose`), in the given order."""
    if not has_rotations(poses):
        raise ValueError("these poses carry no joint rotations: the engine emits joint positions only")
    root = np.stack([np.asarray(p.root_m, float) for p in poses])
    rots = np.stack([np.asarray(p.local_rotations, float) for p in poses])
    return Motion(skeleton, float(fps), root, rots, name)
