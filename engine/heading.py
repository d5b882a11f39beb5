"""Seed 000's heading rule, in a module of its own (numpy only).

Why not in `engine.mocap.ground` alone: the gateway's camera tracker applies the rule to every frame on the court's
small board, and importing `engine.mocap` (and the scipy it pulls in) cost the gateway ~60 MB of resident memory
for one three-line function (issue 20's board budget is 100 MB). `engine.mocap` re-exports both names, so the rule
still has one definition for the live tracker, its synthetic ground truth and the engine's take loader.
"""
from __future__ import annotations

import numpy as np

#: Seed 000's camera heading rule: above this ground speed a player faces where they run, below it the net.
SEED_HEADING_SPEED_MPS = 2.0


def seed_heading_rule(position_m: np.ndarray, velocity_mps: np.ndarray,
                      speed_threshold_mps: float = SEED_HEADING_SPEED_MPS) -> np.ndarray:
    """Heading (rad) by seed 000's rule from ground position and velocity (..., 2) = court (x, y) = world (x, z).

    Direction of motion above the speed threshold, otherwise facing the net: heading 0 (+Z) from the near side
    (y <= 0), pi from the far side. One definition serves the live tracker, its synthetic ground truth and the
    engine's take loader, so all three agree on what "facing the net" means."""
    position_m, velocity_mps = np.asarray(position_m, float), np.asarray(velocity_mps, float)
    moving = np.hypot(velocity_mps[..., 0], velocity_mps[..., 1]) > speed_threshold_mps
    facing_net = np.where(position_m[..., 1] <= 0.0, 0.0, np.pi)
    return np.where(moving, np.arctan2(velocity_mps[..., 0], velocity_mps[..., 1]), facing_net)
