"""The errors issue 11 judges by, per frame, from world joint positions alone (so every engine and baseline is
measured the same way, whatever it reports about itself).

* global joint error: mean over the seed-000 joint set of the world distance (root drift included);
* root-relative joint error: the same, each pose in its own root frame (ground origin under joint 0, facing
  +Z by its hips heading) -- what the pose alone gets right;
* root position error: ground (x, z) distance of joint 0;
* heading error: |wrap(hips heading difference)|.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.graph.poses import root_local
from engine.mocap import Skeleton, error_joint_indices, heading_from_positions, joint_roles, wrap_angle


@dataclass
class FrameErrors:
    """Per-frame errors of one prediction (all (T,))."""

    global_cm: np.ndarray
    root_relative_cm: np.ndarray
    position_cm: np.ndarray
    heading_deg: np.ndarray


def hips_heading(joints_m: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    roles = joint_roles(skeleton)
    return heading_from_positions(joints_m, roles["left_hip"], roles["right_hip"])


def frame_errors(pred_m: np.ndarray, true_m: np.ndarray, skeleton: Skeleton) -> FrameErrors:
    """Errors of predicted world joints (T, J, 3) against the truth (T, J, 3), metres in, cm / deg out."""
    if pred_m.shape != true_m.shape:
        raise ValueError(f"prediction {pred_m.shape} and truth {true_m.shape} differ in shape")
    joints = error_joint_indices(skeleton)
    heads = [hips_heading(p, skeleton) for p in (pred_m, true_m)]
    grounds = [p[:, 0, [0, 2]] for p in (pred_m, true_m)]
    local = [root_local(p[:, joints], g, h) for p, g, h in zip((pred_m, true_m), grounds, heads)]
    return FrameErrors(
        global_cm=100 * np.linalg.norm(pred_m[:, joints] - true_m[:, joints], axis=2).mean(axis=1),
        root_relative_cm=100 * np.linalg.norm(local[0] - local[1], axis=2).mean(axis=1),
        position_cm=100 * np.linalg.norm(grounds[0] - grounds[1], axis=1),
        heading_deg=np.degrees(np.abs(wrap_angle(heads[0] - heads[1]))))


def per_second(values: np.ndarray, fps: float) -> np.ndarray:
    """Mean of `values` over each whole second of the take (the last, partial second included): a loop trap or
    a lost track shows as a run of high seconds."""
    values = np.asarray(values, float)
    edges = np.arange(0, len(values), int(round(fps)))
    return np.add.reduceat(values, edges) / np.diff(np.r_[edges, len(values)])


def concat(errors: list[FrameErrors]) -> FrameErrors:
    return FrameErrors(*(np.concatenate([getattr(e, f) for e in errors])
                         for f in ("global_cm", "root_relative_cm", "position_cm", "heading_deg")))


def summary(errors: list[FrameErrors]) -> dict[str, float]:
    """Means over every frame of every take (the paper's way), plus the worst one-second global error."""
    e = concat(errors)
    return {"global_cm": float(e.global_cm.mean()), "root_relative_cm": float(e.root_relative_cm.mean()),
            "position_cm": float(e.position_cm.mean()), "heading_deg": float(e.heading_deg.mean()),
            "frames": int(len(e.global_cm))}
