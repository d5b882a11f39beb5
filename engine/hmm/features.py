"""Body features X and IMU features Y per frame (spec B1); `engine.hmm.pose_decoder` decodes X back to a pose.

X_t = [local joint quaternions (root with its heading removed, w >= 0), root ground displacement since t-1 in
the heading frame of t-1 with the root height in the vertical slot (m), heading change (rad)]. Joint angular velocities (also in the paper's X) are left
out: the output only needs poses and root motion, and they would double the regression size.
Y_t = per IMU [acc (g, sensor frame), gyro (rad/s, sensor frame), tilt (up in sensor axes)] -- the channels
`HMMConfig.imu_channels` names (acc always; the paper's model is acc + gyro).
"""
from __future__ import annotations

import numpy as np

from engine.mocap import Motion, SensorPlacement, virtual_accelerometers, virtual_gyroscopes
from engine.mocap.orientation import virtual_orientations
from engine.olng.pose import reference_quats, split_heading


def body_features(motion: Motion) -> np.ndarray:
    """(F, J*4 + 4) body features of a clip."""
    heading, tilt = split_heading(motion.rotations[:, 0])
    heading = np.unwrap(heading)
    quats = motion.rotations.copy()
    quats[:, 0] = tilt
    quats = np.where(quats[..., :1] < 0, -quats, quats)
    step = np.diff(motion.root_positions_m, axis=0, prepend=motion.root_positions_m[:1])
    c, s = np.cos(np.r_[heading[0], heading[:-1]]), np.sin(np.r_[heading[0], heading[:-1]])
    # the vertical slot holds the root HEIGHT, not its change: integrating regressed height steps drifts
    local = np.stack([c * step[:, 0] - s * step[:, 2], motion.root_positions_m[:, 1], s * step[:, 0] + c * step[:, 2]], axis=1)
    dheading = np.diff(heading, prepend=heading[0])
    return np.concatenate([quats.reshape(len(quats), -1), local, dheading[:, None]], axis=1)


def align_hemispheres(bodies: list[np.ndarray]) -> list[np.ndarray]:
    """Flip each joint quaternion of every frame onto the hemisphere of the per-joint mean over all clips.

    WHY: the model averages quaternions linearly (templates, interpolation). The usual w >= 0 convention flips
    sign frame to frame for joints held near 180 degrees (Bandai's legs at rest), which ruins those averages."""
    joints = (bodies[0].shape[1] - 4) // 4
    quats = [b[:, : joints * 4].reshape(len(b), joints, 4) for b in bodies]
    ref = reference_quats(np.concatenate(quats))
    out = []
    for body, q in zip(bodies, quats):
        sign = np.where(np.einsum("fjk,jk->fj", q, ref) < 0, -1.0, 1.0)
        aligned = body.copy()
        aligned[:, : joints * 4] = (q * sign[..., None]).reshape(len(body), -1)
        out.append(aligned)
    return out


def imu_features(motion: Motion, placements: list[SensorPlacement]) -> tuple[np.ndarray, np.ndarray]:
    """(acc_g (F, S, 3), gyro_rps (F, S, 3)) of the worn IMUs."""
    return virtual_accelerometers(motion, placements), virtual_gyroscopes(motion, placements)


def imu_orientations(motion: Motion, placements: list[SensorPlacement]) -> np.ndarray:
    """(F, S, 4) true sensor -> world quaternions of the worn IMUs (the tilt channel's source)."""
    return virtual_orientations(motion, placements)


IMU_CHANNELS = {"acc+gyro": 6, "acc": 3, "acc+tilt": 6, "acc+gyro+tilt": 9}  # feature width per IMU


def channel_set(imu_channels: str) -> tuple[bool, bool]:
    """(uses gyro, uses tilt) of an `HMMConfig.imu_channels` value; refuses an unknown one."""
    if imu_channels not in IMU_CHANNELS:
        raise ValueError(f"imu_channels must be one of {sorted(IMU_CHANNELS)}, not {imu_channels!r}")
    parts = imu_channels.split("+")
    return "gyro" in parts, "tilt" in parts


def stack_imu(acc_g: np.ndarray, gyro_rps: np.ndarray | None, tilt: np.ndarray | None = None) -> np.ndarray:
    """(..., S, 3) blocks -> (..., w S) IMU feature vectors, per IMU [acc, gyro, tilt] of those given (not None)."""
    parts = [p for p in (acc_g, gyro_rps, tilt) if p is not None]
    return np.concatenate(parts, axis=-1).reshape(acc_g.shape[:-2] + (-1,))
