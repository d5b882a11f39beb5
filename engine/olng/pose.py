"""Pose vectors and batched forward kinematics in the root frame, on plain arrays.

WHY our own compact FK: the energy minimiser evaluates FK for (1 + subspace dims) candidate poses per Jacobian,
so it needs FK that is batched over candidates and starts from rotation vectors; the general
`engine.mocap.forward_kinematics` works on whole `Motion` objects instead.

Pose vector q (spec A2.1/A2.8): the local rotation of every joint as a rotation vector (radians), (J*3,).
The root's heading (yaw about +Y) is removed so database poses do not spread by facing direction; its
pitch/roll stay (they supply the tilt the control term needs to remove gravity).
Joint positions x are in the root frame: x = R_root^T (p_j - p_root), metres.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

UP = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class Rig:
    """The skeleton as arrays: parent index per joint (-1 for the root, parents before children) and the
    rest offset of each joint from its parent in metres."""

    names: tuple[str, ...]
    parents: np.ndarray   # (J,) int
    offsets_m: np.ndarray  # (J, 3)

    def __post_init__(self) -> None:
        parents = np.asarray(self.parents)
        if parents[0] != -1 or np.any(parents[1:] >= np.arange(1, len(parents))):
            raise ValueError("rig joints must be ordered root first, every parent before its children")


def quat_to_matrix(quat: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (w, x, y, z) -> (..., 3, 3) rotation matrices."""
    w, x, y, z = np.moveaxis(np.asarray(quat, dtype=float), -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of (..., 4) quaternions (w, x, y, z)."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        -1,
    )


def quat_to_rotvec(quat: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions -> (..., 3) rotation vectors (radians), shortest arc (w >= 0)."""
    q = np.where(quat[..., :1] < 0, -quat, quat)
    sin_half = np.linalg.norm(q[..., 1:], axis=-1)
    angle = 2.0 * np.arctan2(sin_half, q[..., 0])
    scale = np.where(sin_half > 1e-12, angle / np.maximum(sin_half, 1e-12), 2.0)
    return q[..., 1:] * scale[..., None]


def rotvec_to_quat(rotvec: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors -> (..., 4) unit quaternions (w, x, y, z)."""
    angle = np.linalg.norm(rotvec, axis=-1)
    half = 0.5 * angle
    scale = np.where(angle > 1e-12, np.sin(half) / np.maximum(angle, 1e-12), 0.5)
    return np.concatenate([np.cos(half)[..., None], rotvec * scale[..., None]], axis=-1)


def rotvec_to_matrix(rotvec: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors -> (..., 3, 3) matrices (Rodrigues)."""
    angle = np.linalg.norm(rotvec, axis=-1)[..., None, None]
    safe = np.where(angle > 1e-12, angle, 1.0)
    kx, ky, kz = np.moveaxis(rotvec, -1, 0)
    zero = np.zeros_like(kx)
    k = np.stack([np.stack([zero, -kz, ky], -1), np.stack([kz, zero, -kx], -1), np.stack([-ky, kx, zero], -1)], -2)
    k = k / safe
    small = angle <= 1e-12
    sin = np.where(small, 0.0, np.sin(angle))
    one_minus_cos = np.where(small, 0.0, 1.0 - np.cos(angle))
    eye = np.broadcast_to(np.eye(3), k.shape)
    return eye + sin * k + one_minus_cos * (k @ k)


def heading_of_matrix(rot: np.ndarray) -> np.ndarray:
    """Heading (radians, 0 = facing +Z, CCW from above) of (..., 3, 3) root rotations: atan2(fwd_x, fwd_z)
    of the root's local +Z axis (CONTRACTS.md)."""
    return np.arctan2(rot[..., 0, 2], rot[..., 2, 2])


def yaw_quat(heading_rad: np.ndarray) -> np.ndarray:
    """Quaternions of rotations about +Y by heading_rad."""
    half = 0.5 * np.asarray(heading_rad, dtype=float)
    zero = np.zeros_like(half)
    return np.stack([np.cos(half), zero, np.sin(half), zero], -1)


def split_heading(root_quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Root quaternions (F, 4) -> (heading_rad (F,), tilt quaternion (F, 4)) with root = yaw(heading) * tilt."""
    heading = heading_of_matrix(quat_to_matrix(root_quat))
    yaw = yaw_quat(heading)
    yaw_inv = yaw * np.array([1.0, -1.0, -1.0, -1.0])
    return heading, quat_multiply(yaw_inv, root_quat)


def pose_vectors(local_quats: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local joint quaternions (F, J, 4) -> (pose vectors q (F, J*3) with root heading removed, heading (F,))."""
    heading, tilt = split_heading(local_quats[:, 0])
    quats = local_quats.copy()
    quats[:, 0] = tilt
    frames, joints = quats.shape[:2]
    return quat_to_rotvec(quats).reshape(frames, joints * 3), heading


def local_matrices(q: np.ndarray, joints: int) -> np.ndarray:
    """Pose vectors (B, J*3) -> local rotation matrices (B, J, 3, 3)."""
    return rotvec_to_matrix(q.reshape(q.shape[0], joints, 3))


def fk_root_frame(rig: Rig, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Batched FK in the root frame: pose vectors (B, J*3) -> (positions (B, J, 3) m relative to the root in the
    root's own frame, joint rotations (B, J, 3, 3) relative to the root frame).

    The root's rotation is replaced by the identity, which is exactly what R_root^T (p - p_root) means."""
    joints = len(rig.parents)
    local = local_matrices(q, joints)
    batch = q.shape[0]
    rot = np.empty((batch, joints, 3, 3))
    pos = np.empty((batch, joints, 3))
    rot[:, 0] = np.eye(3)
    pos[:, 0] = 0.0
    for j in range(1, joints):
        p = rig.parents[j]
        rot[:, j] = rot[:, p] @ local[:, j]
        pos[:, j] = pos[:, p] + rot[:, p] @ rig.offsets_m[j]
    return pos, rot
