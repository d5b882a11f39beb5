"""Error measures shared by the OLNG and HMM evaluations, in the same format as engine.graph's leave-one-out
table (joint error cm in each pose's own ground/heading frame over the seed-000 joint set, root position error cm,
heading error deg), plus the paper's own measure (RMS over all joints in the full root frame, cm).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.graph.evaluate import root_local
from engine.mocap import Skeleton, error_joint_indices, heading_from_positions, joint_roles, wrap_angle


@dataclass
class ClipErrors:
    """Per-frame errors of one reconstructed clip."""

    joint_cm: np.ndarray      # (F,) mean joint distance, heading frame, error joints (engine.graph's measure)
    rms_root_cm: np.ndarray   # (F,) RMS over all joints in the full root frame (Tautges et al.)
    position_cm: np.ndarray   # (F,) root ground-position error
    heading_deg: np.ndarray   # (F,) body-heading error


def root_frame(world_m: np.ndarray, root_rot: np.ndarray) -> np.ndarray:
    """World joints (F, J, 3) -> R_root^T (p - p_root)."""
    return np.einsum("fji,fkj->fki", root_rot, world_m - world_m[:, :1])


def score(pred_world_m: np.ndarray, pred_root_rot: np.ndarray, true_world_m: np.ndarray, true_root_rot: np.ndarray,
          skeleton: Skeleton) -> ClipErrors:
    """Errors of a reconstruction against the truth, both as world joint positions (F, J, 3) and root rotations."""
    roles = joint_roles(skeleton)
    joints = error_joint_indices(skeleton)
    heads = [heading_from_positions(p, roles["left_hip"], roles["right_hip"]) for p in (pred_world_m, true_world_m)]
    grounds = [p[:, 0, [0, 2]] for p in (pred_world_m, true_world_m)]
    a = root_local(pred_world_m[:, joints], grounds[0], heads[0])
    b = root_local(true_world_m[:, joints], grounds[1], heads[1])
    diff = root_frame(pred_world_m, pred_root_rot) - root_frame(true_world_m, true_root_rot)
    return ClipErrors(
        joint_cm=100 * np.linalg.norm(a - b, axis=2).mean(axis=1),
        rms_root_cm=100 * np.sqrt((diff**2).sum(-1).mean(-1)),
        position_cm=100 * np.linalg.norm(grounds[0] - grounds[1], axis=1),
        heading_deg=np.degrees(np.abs(wrap_angle(heads[0] - heads[1]))),
    )


def summarise(errors: list[ClipErrors]) -> dict[str, float]:
    """Mean (sd) over all frames of all clips, as engine.graph.evaluate.summarise reports."""
    j = np.concatenate([e.joint_cm for e in errors])
    r = np.concatenate([e.rms_root_cm for e in errors])
    p = np.concatenate([e.position_cm for e in errors])
    h = np.concatenate([e.heading_deg for e in errors])
    return {"joint_cm": j.mean(), "joint_sd": j.std(), "rms_root_cm": r.mean(), "pos_cm": p.mean(), "pos_sd": p.std(),
            "head_deg": h.mean(), "head_sd": h.std(), "frames": len(j)}


def format_table(rows: dict[str, dict[str, float]]) -> str:
    """The common report table: one row per method/setting."""
    head = f"{'method':<28}{'joint cm':>10}{'(sd)':>8}{'rms root cm':>13}{'pos cm':>9}{'head deg':>10}{'frames':>8}"
    lines = [head, "-" * len(head)]
    for name, s in rows.items():
        lines.append(f"{name:<28}{s['joint_cm']:>10.2f}{s['joint_sd']:>8.2f}{s.get('rms_root_cm', float('nan')):>13.2f}"
                     f"{s['pos_cm']:>9.1f}{s['head_deg']:>10.1f}{int(s['frames']):>8d}")
    return "\n".join(lines)
