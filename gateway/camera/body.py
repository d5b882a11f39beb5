"""A capsule-built standing/running body for the synthetic camera.

Why capsules rather than a flat ellipse: a 3-D body seen by an oblique camera has parallax (the head lands metres
away from the feet on the ground plane), which is exactly the error the tracker's ground-point logic must handle.
Legs and arms swing with a gait phase so the silhouette changes like a real runner's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gateway.camera.paths import PlayerState

#: Colours (BGR) of legs/arms (skin), shorts, shirt, head (hair).
SKIN, SHORTS, SHIRT, HAIR = (110, 150, 200), (40, 40, 45), (40, 210, 240), (40, 60, 90)
STRIDE_M = 1.6


@dataclass(frozen=True)
class Capsules:
    """``start_m``/``end_m`` (C, 3) court-frame axis endpoints, ``radius_m`` (C,), ``colour`` list of BGR."""

    start_m: np.ndarray
    end_m: np.ndarray
    radius_m: np.ndarray
    colour: list[tuple[int, int, int]]


def body_capsules(state: PlayerState, gait_phase_rad: float) -> Capsules:
    """Capsules of a 1.8 m player standing at ``state`` (pelvis above ``(x_m, y_m)``), legs at ``gait_phase_rad``."""
    swing = min(0.32, 0.1 * state.speed_mps)
    s, c = np.sin(gait_phase_rad), np.cos(gait_phase_rad)
    # Local frame: forward, lateral (to the player's right), up.
    local = {
        "pelvis": (0.0, 0.0, 0.95),
        "hip_l": (0.0, -0.1, 0.92), "hip_r": (0.0, 0.1, 0.92),
        "foot_l": (swing * s, -0.14, 0.06 + 0.1 * swing * max(0.0, c)),
        "foot_r": (-swing * s, 0.14, 0.06 + 0.1 * swing * max(0.0, -c)),
        "neck": (0.0, 0.0, 1.45), "head": (0.02, 0.0, 1.66),
        "shoulder_l": (0.0, -0.19, 1.42), "shoulder_r": (0.0, 0.19, 1.42),
        "hand_l": (-0.6 * swing * s, -0.25, 0.86), "hand_r": (0.6 * swing * s, 0.25, 0.86),
    }
    for side in ("l", "r"):
        hip, foot = np.array(local[f"hip_{side}"]), np.array(local[f"foot_{side}"])
        local[f"knee_{side}"] = tuple((hip + foot) / 2 + np.array([0.06, 0.0, 0.02]))
        local[f"toe_{side}"] = tuple(foot + np.array([0.16, 0.0, -0.02]))
    bones = [
        ("hip_l", "knee_l", 0.075, SKIN), ("knee_l", "foot_l", 0.06, SKIN), ("foot_l", "toe_l", 0.05, SHORTS),
        ("hip_r", "knee_r", 0.075, SKIN), ("knee_r", "foot_r", 0.06, SKIN), ("foot_r", "toe_r", 0.05, SHORTS),
        ("hip_l", "hip_r", 0.12, SHORTS), ("pelvis", "neck", 0.17, SHIRT),
        ("shoulder_l", "hand_l", 0.05, SKIN), ("shoulder_r", "hand_r", 0.05, SKIN), ("head", "head", 0.11, HAIR),
    ]
    h = state.heading_rad
    forward = np.array([np.sin(h), np.cos(h), 0.0])
    right = np.array([np.cos(h), -np.sin(h), 0.0])
    basis = np.stack([forward, right, np.array([0.0, 0.0, 1.0])])  # rows map local axes to court
    origin = np.array([state.x_m, state.y_m, state.lift_m])
    start = np.array([local[a] for a, _, _, _ in bones]) @ basis + origin
    end = np.array([local[b] for _, b, _, _ in bones]) @ basis + origin
    return Capsules(start, end, np.array([r for _, _, r, _ in bones]), [col for *_, col in bones])


def capsule_surface_points(capsules: Capsules, n_dirs: int = 26) -> np.ndarray:
    """Points (C, 2 * n_dirs, 3) on the end spheres of each capsule: their convex hull in any view is the
    capsule's silhouette (to the sampling resolution)."""
    k = np.arange(n_dirs) + 0.5
    polar = np.arccos(1 - 2 * k / n_dirs)
    azimuth = np.pi * (1 + 5**0.5) * k
    dirs = np.column_stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])
    offsets = capsules.radius_m[:, None, None] * dirs[None]
    return np.concatenate([capsules.start_m[:, None] + offsets, capsules.end_m[:, None] + offsets], axis=1)
