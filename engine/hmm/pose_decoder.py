"""Body features X (`engine.hmm.features`) back to a pose, one frame at a time: the root's ground step and heading
change integrated, pulled towards the camera's fixes, and the local joint rotations.

Why one frame at a time for everyone: the live engine (`engine.hmm.online_engine`) and the batch reconstruction
(`engine.hmm.evaluation.reconstruct`) decode with this one object, so a take gives the same poses live and offline
(issue 29), camera warp included."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from engine.mocap import heading_from_positions, joint_roles, pose_joint_positions, quaternions
from engine.olng.pose import yaw_quat

if TYPE_CHECKING:
    from engine.graph.warp import RootWarp


class PoseDecoder:
    """Decodes each frame's body features into (root (3,) m, local rotations (J, 4) wxyz) of ``joints`` joints.

    The first frame stands at ``start_m`` (ground x, z) facing ``heading_rad``; each later frame steps by its own
    ground displacement (in the previous frame's heading frame) and turns by its heading change; the root height
    is the frame's own. A camera fix (ground (2,) m and/or body heading rad) pulls the root towards it after the
    step by the bounded root warp (engine/graph/warp.py); the first fix places it. The camera reports where the
    hips face, the integrated heading is the root's twist: their offset is read off this frame's pose, which needs
    ``skeleton`` (without one the twist is taken as the body heading)."""

    def __init__(self, joints: int, fps: float, root_warp: RootWarp | None = None, skeleton: Any = None,
                 start_m: np.ndarray = np.zeros(2), heading_rad: float = 0.0) -> None:
        from engine.graph.warp import RootWarp

        self.joints = joints
        self.fps = fps
        self.root_warp = RootWarp() if root_warp is None else root_warp
        self.skeleton = skeleton
        roles = None if skeleton is None else joint_roles(skeleton)
        self._hips = None if roles is None else (roles["left_hip"], roles["right_hip"])
        self.ground = complex(start_m[0], start_m[1])  # root on the ground, x + i z m
        self.heading_rad = float(heading_rad)           # integrated root heading
        self._started = False
        self._fixed = False                              # has a camera fix placed the root yet?

    def step(self, body: np.ndarray, fix_m: np.ndarray | None = None,
             fix_heading_rad: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The next frame's (root, local rotations) from its body features and camera fix (None / NaN: none)."""
        if self._started:
            local = body[self.joints * 4: self.joints * 4 + 3]
            self.ground += complex(local[0], local[2]) * np.exp(-1j * self.heading_rad)
            self.heading_rad += float(body[-1])
        self._started = True
        self._follow_camera(body, fix_m, fix_heading_rad)
        return self.pose(body, self.heading_rad)

    def pose(self, body: np.ndarray, heading_rad: float) -> tuple[np.ndarray, np.ndarray]:
        """(root (3,) m at the current ground position, local rotations (J, 4)) of ``body`` turned to this heading."""
        rotations = body[: self.joints * 4].reshape(self.joints, 4)
        rotations = rotations / np.linalg.norm(rotations, axis=-1, keepdims=True)
        rotations[0] = quaternions.multiply(yaw_quat(np.array(heading_rad)), rotations[0])
        return np.array([self.ground.real, body[self.joints * 4 + 1], self.ground.imag]), rotations

    def _follow_camera(self, body: np.ndarray, fix_m: np.ndarray | None, fix_heading_rad: float | None) -> None:
        from engine.graph.warp import warp_one

        pos = None if fix_m is None or np.any(np.isnan(fix_m)) else complex(fix_m[0], fix_m[1])
        head = None if fix_heading_rad is None or np.isnan(fix_heading_rad) else float(fix_heading_rad)
        if pos is None and head is None:
            return
        offset = 0.0  # where the hips face minus the root's twist
        if head is not None and self._hips is not None:
            joints = pose_joint_positions(self.skeleton, *self.pose(body, 0.0))
            offset = float(heading_from_positions(joints[None], *self._hips)[0])
        if not self._fixed:
            self.ground = pos if pos is not None else self.ground
            self.heading_rad = head - offset if head is not None else self.heading_rad
            self._fixed = True
            return
        self.ground, body_heading = warp_one(self.ground, self.heading_rad + offset, pos, head, self.root_warp,
                                             self.fps)
        self.heading_rad = body_heading - offset
