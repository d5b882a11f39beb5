"""Ground-plane helpers: heading, 2-D position and foot contacts.

Heading follows docs/CONTRACTS.md: yaw of the body's forward direction about +Y, 0 = facing +Z, positive
counter-clockwise seen from above, `atan2(fwd_x, fwd_z)`. Forward is taken from the *hip joints*
(forward = (left_hip - right_hip) x up), not from the root joint's frame, because joint frames mean
different things in different files (Bandai's pelvis frame has X up) while the hips are always the hips."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.mocap.roles import joint_roles
from engine.mocap.skeleton import Motion, forward_kinematics


def heading_from_positions(positions_m: np.ndarray, left_hip: int, right_hip: int) -> np.ndarray:
    """(F,) heading in radians from world joint positions (F, J, 3)."""
    lateral = positions_m[:, left_hip] - positions_m[:, right_hip]
    # forward = lateral x up = (-lat_z, 0, lat_x)
    return np.arctan2(-lateral[:, 2], lateral[:, 0])


def root_heading(motion: Motion, positions_m: np.ndarray | None = None) -> np.ndarray:
    """(F,) heading of the body in radians (pass FK positions if already computed)."""
    roles = joint_roles(motion.skeleton)
    if positions_m is None:
        positions_m, _ = forward_kinematics(motion)
    return heading_from_positions(positions_m, roles["left_hip"], roles["right_hip"])


def ground_positions(motion: Motion) -> np.ndarray:
    """(F, 2) root position on the ground plane, (x, z) metres."""
    return motion.root_positions_m[:, [0, 2]].copy()


def wrap_angle(angle_rad: np.ndarray) -> np.ndarray:
    """Wrap to [-pi, pi)."""
    return (np.asarray(angle_rad) + np.pi) % (2 * np.pi) - np.pi


@dataclass(frozen=True)
class ContactThresholds:
    """Foot-contact test (the paper leaves it open; these values give ~60 % stance per foot on CMU walks).

    A foot is in contact when its heel (ankle joint) or toe (ball joint) is both low and slow:
    height above that joint's floor level < `height_m` and speed < `speed_mps`. The floor level of each
    joint is its `floor_percentile` height over the clip (robust to a floor that is not at y = 0, and to
    the ankle sitting higher than the toe); runs of contact shorter than `min_frames` are dropped."""

    height_m: float = 0.05
    speed_mps: float = 0.7
    floor_percentile: float = 5.0
    min_frames: int = 2


def foot_contacts(motion: Motion, thresholds: ContactThresholds = ContactThresholds(),
                  positions_m: np.ndarray | None = None) -> np.ndarray:
    """(F, 2) bool foot-contact flags, columns [left, right]."""
    roles = joint_roles(motion.skeleton)
    if positions_m is None:
        positions_m, _ = forward_kinematics(motion)
    out = np.zeros((motion.n_frames, 2), bool)
    for col, side in enumerate(("left", "right")):
        joints = [roles[f"{side}_ankle"], roles[f"{side}_toe"]]
        p = positions_m[:, joints]  # (F, 2, 3)
        height = p[..., 1] - np.percentile(p[..., 1], thresholds.floor_percentile, axis=0)
        speed = np.linalg.norm(np.gradient(p, axis=0), axis=-1) * motion.fps if motion.n_frames > 1 else np.zeros(height.shape)
        contact = np.any((height < thresholds.height_m) & (speed < thresholds.speed_mps), axis=1)
        out[:, col] = _drop_short_runs(contact, thresholds.min_frames)
    return out


def _drop_short_runs(flags: np.ndarray, min_len: int) -> np.ndarray:
    """Clear runs of True shorter than min_len (single-frame flickers at the threshold)."""
    if min_len <= 1 or not flags.any():
        return flags
    padded = np.concatenate([[False], flags, [False]])
    edges = np.flatnonzero(np.diff(padded.astype(int)))
    starts, stops = edges[::2], edges[1::2]
    out = flags.copy()
    for a, b in zip(starts, stops):
        if b - a < min_len:
            out[a:b] = False
    return out
