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

from engine.mocap import quaternions

UP = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class Rig:
    """The skeleton as arrays: parent index per joint (-1 for the root, parents before children) and the
    rest offset of each joint from its parent in metres."""

    names: tuple[str, ...]
    parents: np.ndarray   # (J,) int
    offsets_m: np.ndarray  # (J, 3)
    end_site: np.ndarray | None = None  # (J,) bool, leaves without rotation channels (kept for BVH output)
    ref_quats: np.ndarray | None = None  # (J, 4) per-joint reference rotation the pose vectors are relative to

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




def rotvec_to_quat(rotvec: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors -> (..., 4) unit quaternions (w, x, y, z)."""
    angle = np.linalg.norm(rotvec, axis=-1)
    half = 0.5 * angle
    scale = np.where(angle > 1e-12, np.sin(half) / np.maximum(angle, 1e-12), 0.5)
    return np.concatenate([np.cos(half)[..., None], rotvec * scale[..., None]], axis=-1)


def rotvec_to_matrix(rotvec: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors -> (..., 3, 3) matrices (Rodrigues: cos I + sin [k]x + (1 - cos) k k^T)."""
    angle = np.linalg.norm(rotvec, axis=-1)
    k = rotvec / np.where(angle > 1e-12, angle, 1.0)[..., None]
    cos, sin = np.cos(angle)[..., None, None], np.sin(angle)[..., None, None]
    kx, ky, kz = k[..., 0], k[..., 1], k[..., 2]
    zero = np.zeros_like(kx)
    cross = np.stack([zero, -kz, ky, kz, zero, -kx, -ky, kx, zero], axis=-1).reshape(k.shape[:-1] + (3, 3))
    return cos * np.eye(3) + sin * cross + (1.0 - cos) * (k[..., :, None] * k[..., None, :])


def yaw_quat(heading_rad: np.ndarray) -> np.ndarray:
    """Quaternions of rotations about +Y by heading_rad."""
    half = 0.5 * np.asarray(heading_rad, dtype=float)
    zero = np.zeros_like(half)
    return np.stack([np.cos(half), zero, np.sin(half), zero], -1)


def split_heading(root_quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Swing-twist split of root quaternions (F, 4) about +Y: (heading_rad (F,), tilt (F, 4)), root = yaw * tilt.

    WHY twist rather than "where the root's +Z points": it does not assume which root axis is forward (Bandai's
    rest pose lies along X), and it is continuous wherever the root is not upside down."""
    heading = 2.0 * np.arctan2(root_quat[..., 2], root_quat[..., 0])
    yaw_inv = yaw_quat(heading) * np.array([1.0, -1.0, -1.0, -1.0])
    return heading, quaternions.multiply(yaw_inv, root_quat)


def reference_quats(tilted_quats: np.ndarray) -> np.ndarray:
    """Per-joint mean rotation (J, 4) of (F, J, 4) quaternions (signs aligned to the first frame, normalised).

    WHY: some skeletons hold joints near 180 degrees at rest (Bandai's legs); rotation vectors wrap there, so
    averaging or PCA of raw rotation vectors mixes +pi and -pi. Pose vectors relative to this reference stay
    small deviations."""
    sign = np.sign(np.einsum("fjk,jk->fj", tilted_quats, tilted_quats[0]))
    mean = (tilted_quats * np.where(sign == 0, 1.0, sign)[..., None]).mean(axis=0)
    norm = np.linalg.norm(mean, axis=-1, keepdims=True)
    return np.where(norm > 1e-9, mean / np.maximum(norm, 1e-9), np.array([1.0, 0.0, 0.0, 0.0]))


def tilted(local_quats: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local joint quaternions (F, J, 4) -> (the same with the root's heading removed, heading (F,))."""
    heading, tilt = split_heading(local_quats[:, 0])
    quats = local_quats.copy()
    quats[:, 0] = tilt
    return quats, heading


def pose_vectors(local_quats: np.ndarray, ref_quats: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Local joint quaternions (F, J, 4) -> (pose vectors q (F, J*3) with root heading removed, relative to
    ref_quats when given, heading (F,))."""
    quats, heading = tilted(local_quats)
    if ref_quats is not None:
        quats = quaternions.multiply(ref_quats * np.array([1.0, -1.0, -1.0, -1.0]), quats)
    frames, joints = quats.shape[:2]
    return quaternions.to_rotvec(quats).reshape(frames, joints * 3), heading


def pose_quats(rig: Rig, q: np.ndarray) -> np.ndarray:
    """Pose vector (J*3,) -> local quaternions (J, 4) (root without heading)."""
    quats = rotvec_to_quat(q.reshape(-1, 3))
    return quats if rig.ref_quats is None else quaternions.multiply(rig.ref_quats, quats)


def local_matrices(rig: Rig, q: np.ndarray) -> np.ndarray:
    """Pose vectors (B, J*3) -> local rotation matrices (B, J, 3, 3)."""
    local = rotvec_to_matrix(q.reshape(q.shape[0], len(rig.parents), 3))
    return local if rig.ref_quats is None else _ref_matrices(rig) @ local


def _ref_matrices(rig: Rig) -> np.ndarray:
    """quat_to_matrix(rig.ref_quats), cached on the rig (FK runs ~1000 times per second)."""
    cached = rig.__dict__.get("_ref_matrices")
    if cached is None:
        cached = quat_to_matrix(rig.ref_quats)
        object.__setattr__(rig, "_ref_matrices", cached)
    return cached


def _fk_levels(rig: Rig) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]:
    """Joints grouped by depth below the root (root excluded), as (joints, their parents, their offsets (n, 3, 1)
    in metres): FK then processes a whole level at once. Cached on the rig (FK runs ~1000 times per second)."""
    cached = rig.__dict__.get("_fk_levels")
    if cached is None:
        parents = np.asarray(rig.parents)
        depth = np.zeros(len(parents), dtype=int)
        for j in range(1, len(parents)):
            depth[j] = depth[parents[j]] + 1
        levels = (np.flatnonzero(depth == d) for d in range(1, depth.max() + 1))
        cached = tuple((level, parents[level], np.asarray(rig.offsets_m, float)[level, :, None]) for level in levels)
        object.__setattr__(rig, "_fk_levels", cached)
    return cached


def fk_root_frame(rig: Rig, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Batched FK in the root frame: pose vectors (B, J*3) -> (positions (B, J, 3) m relative to the root in the
    root's own frame, joint rotations (B, J, 3, 3) relative to the root frame).

    The root's rotation is replaced by the identity, which is exactly what R_root^T (p - p_root) means."""
    return fk_local(rig, local_matrices(rig, q))


def fk_local(rig: Rig, local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`fk_root_frame` from local rotation matrices (B, J, 3, 3) (`local_matrices`: a caller that also needs the
    root's tilt, local[:, 0], converts the rotation vectors once). Joints are processed a depth level at a time
    (about 10 levels for a 38-joint CMU skeleton), because the energy calls this ~10^3 times per second."""
    batch, joints = local.shape[:2]
    rot = np.empty((batch, joints, 3, 3))
    pos = np.empty((batch, joints, 3))
    rot[:, 0] = np.eye(3)
    pos[:, 0] = 0.0
    for level, par, offsets in _fk_levels(rig):
        parent_rot = rot[:, par]
        rot[:, level] = parent_rot @ local[:, level]
        pos[:, level] = pos[:, par] + (parent_rot @ offsets)[..., 0]
    return pos, rot
