"""The decided pose: what an engine emits and every sink reads (issue 29).

A pose is the root position and the local joint rotations of the engine's skeleton; joint positions are derived
from them by forward kinematics, never computed on a side path. Why: the console drew one pose (blended and
posed positions), the BVH file another (rotation blend, no posing) and the live streams a third, so what a user
exported was not what the engine knew. With one pose, the BVH written from the rotations gives back the saved
joint positions (a test checks 1 mm), live and offline.

`decided_pose` builds an `EnginePose` from rotations; `poses_to_motion` turns a run of decided poses into the
`engine.mocap.Motion` that the BVH file and the BVH / VMC streams write; `exported_joint_positions` writes that
BVH and reads it back (what a user's tool would see), so evaluation scores the file beside the shown poses."""
from __future__ import annotations

import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from engine.mocap import Motion, Skeleton, forward_kinematics, pose_joint_positions, read_bvh, write_bvh

from .engines import EnginePose


def decided_pose(skeleton: Skeleton, t: int, root_m: np.ndarray, local_rotations: np.ndarray,
                 confidence: float | None = None) -> EnginePose:
    """The `EnginePose` of push index ``t`` whose joints are the forward kinematics of the rotations."""
    root = np.asarray(root_m, float)
    rots = np.asarray(local_rotations, float)
    return EnginePose(t, pose_joint_positions(skeleton, root, rots), confidence, root, rots)


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


def exported_joint_positions(motion: Motion) -> np.ndarray:
    """(T, J, 3) world joints m of ``motion`` after a round trip through a BVH file (`write_bvh`, then
    `read_bvh`): the Euler angles and the printed digits are what any tool reading the file gets."""
    with tempfile.TemporaryDirectory(prefix="courtside-bvh-") as folder:
        path = Path(folder) / "exported.bvh"
        write_bvh(path, motion, units="cm")
        return forward_kinematics(read_bvh(path, scale="cm"))[0]
