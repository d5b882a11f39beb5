"""Edge metadata: what traversing an edge alpha -> beta does to the root and reads on the sensors.

(a) heading offset = wrap(heading(beta) - heading(alpha)) (rad); (b) ground-plane position offset of the root,
expressed in the local frame of alpha (rotated by -heading(alpha)), metres; (c) virtual accelerations (g) of
every configured sensor on arriving at beta. Many edges replay the same motion (a transition into j replays
the natural step j-1 -> j), so edges point into shared metadata rows instead of copying them.
"""
from __future__ import annotations

import numpy as np

from .geometry import rotate_ground, wrap_angle


def step_offsets(heading_a: np.ndarray, ground_a: np.ndarray, heading_b: np.ndarray,
                 ground_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(heading offset (rad), local ground offset (m) in alpha's frame) for steps alpha -> beta (vectorised)."""
    dheading = wrap_angle(np.asarray(heading_b) - np.asarray(heading_a))
    dpos = rotate_ground(np.asarray(ground_b) - np.asarray(ground_a), -np.asarray(heading_a))
    return dheading, dpos


def advance(ground_m: np.ndarray, heading_rad: np.ndarray, dpos_local_m: np.ndarray,
            dheading_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Global (ground, heading) after traversing edges with the given offsets (eq. 5 of seed 000)."""
    return ground_m + rotate_ground(dpos_local_m, heading_rad), heading_rad + dheading_rad

