"""Where the 3-D view draws each athlete on the court, and how far the follow camera stands to frame them all.

Why the court decides and not the engine: an engine's root lives in its own world (dead reckoning from the
accelerometers, or a path pulled towards camera fixes) and is not anchored to the court, so two athletes' roots
can coincide or drift off the court. The overhead camera's track is the court's word on where each athlete
stands (the minimap draws the same track); each skeleton is drawn with its root over that spot, its pose
otherwise as decided. An athlete without a camera track stands at its half's default spot, and the legend says
so (`gui.widgets.skeleton_view`).

Court frame (docs/CONTRACTS.md): x along the net, y towards the far baseline; engine world (X, Z) = (x, y)."""
from __future__ import annotations

import math

import numpy as np

from gui.render.court import COURT_LENGTH_M

BASELINE_SPOT_FROM_NET_M = COURT_LENGTH_M / 2 - 1.5  # where a player without a camera track is drawn: its
                                                      # half's centre, 1.5 m inside the baseline
SIDES = ("near", "far")  # the court config's athlete sides; near is the camera's half (court y < 0)
FOLLOW_DISTANCE_M = 6.0  # the follow camera's distance for one athlete
FRAMING_MARGIN = 1.3      # the athletes' spread across the screen times this fits the view's width
OBLIQUE_RAD = math.radians(12.0)  # the view across two athletes is this far off square to the line between them


def default_spot(side: str | None, index: int) -> np.ndarray:
    """Court (x, y) m of an athlete without a camera track: its side's default spot (``near`` / ``far``), or for
    no side, the first athlete near and the next far, alternating."""
    far = side == "far" if side in SIDES else index % 2 == 1
    return np.array([0.0, BASELINE_SPOT_FROM_NET_M if far else -BASELINE_SPOT_FROM_NET_M])


def track_spot(trail: np.ndarray, t_s: float | None) -> np.ndarray | None:
    """Court (x, y) m at gateway time ``t_s`` on a camera trail (N, 3) [t_s, x_m, y_m] (time order), linearly
    interpolated; a time outside the trail takes its nearest end (a pose decided a lag behind the newest fix, or
    a tracker that lost the player keeps the last spot). None for an empty trail; ``t_s`` None: the newest fix."""
    trail = np.asarray(trail, float).reshape(-1, 3)
    if not len(trail):
        return None
    if t_s is None:
        return trail[-1, 1:3].copy()
    return np.array([np.interp(t_s, trail[:, 0], trail[:, 1]), np.interp(t_s, trail[:, 0], trail[:, 2])])


def place(pose_m: np.ndarray, spot_xy: np.ndarray) -> np.ndarray:
    """Joint positions (J, 3) shifted on the ground so the root (joint 0) stands over court spot (x, y); heights
    and the pose relative to the root unchanged."""
    shift = np.array([spot_xy[0] - pose_m[0, 0], 0.0, spot_xy[1] - pose_m[0, 2]])
    return pose_m + shift


def across_yaw_rad(roots_m: np.ndarray) -> float | None:
    """Orbit yaw (0 looks along +Z, `gui.render.camera.OrbitCamera`) that looks across the line through the first
    and last roots (N, 3), ``OBLIQUE_RAD`` off square so their depths read: with the athletes side by side on
    screen, the view's wider axis holds their spread. None for one root (or two on one spot)."""
    roots = np.asarray(roots_m, float).reshape(-1, 3)
    dx, dz = roots[-1, 0] - roots[0, 0], roots[-1, 2] - roots[0, 2]
    if len(roots) < 2 or math.hypot(dx, dz) < 1e-6:
        return None
    return math.atan2(dz, -dx) + OBLIQUE_RAD  # looking along (dz, -dx): square to the line between them


def framing_distance_m(roots_m: np.ndarray, fovy_rad: float, aspect: float, yaw_rad: float) -> float:
    """Follow-camera distance that keeps every root (N, 3) in view: the one-athlete distance, or their spread
    across the screen (along the view's right at ``yaw_rad``) over the view's width, with a margin."""
    roots = np.asarray(roots_m, float).reshape(-1, 3)
    if len(roots) < 2:
        return FOLLOW_DISTANCE_M
    right = np.array([-math.cos(yaw_rad), math.sin(yaw_rad)])  # `OrbitCamera.right_m` on the court's (x, y)
    across = float(np.ptp(roots[:, [0, 2]] @ right))
    along = float(np.ptp(roots[:, [0, 2]] @ np.array([math.sin(yaw_rad), math.cos(yaw_rad)])))
    half_width = math.tan(fovy_rad / 2.0) * aspect
    return max(FOLLOW_DISTANCE_M, FRAMING_MARGIN * across / (2.0 * half_width) + along / 2.0)
