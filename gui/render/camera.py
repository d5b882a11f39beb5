"""View/projection matrices and an orbit camera with follow and static modes.

Matrices are numpy row-major 4x4 (column vectors: ``clip = P @ V @ p``); send ``m.T`` to GLSL, which is
column-major. World frame is the engine's: Y up, ground plane X-Z, metres (docs/CONTRACTS.md)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from gui.render.placement import FOLLOW_DISTANCE_M, across_yaw_rad, framing_distance_m

ACROSS_PITCH_RAD = math.radians(30.0)  # the follow view's pitch at least, looking across several athletes


def perspective(fovy_rad: float, aspect: float, near_m: float, far_m: float) -> np.ndarray:
    """OpenGL perspective projection (right-handed eye space, looking down -Z, depth to [-1, 1])."""
    f = 1.0 / math.tan(fovy_rad / 2.0)
    m = np.zeros((4, 4))
    m[0, 0] = f / aspect
    m[1, 1] = f
    m[2, 2] = (far_m + near_m) / (near_m - far_m)
    m[2, 3] = 2.0 * far_m * near_m / (near_m - far_m)
    m[3, 2] = -1.0
    return m


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = np.array([0.0, 1.0, 0.0])) -> np.ndarray:
    """View matrix placing the eye at ``eye`` looking at ``target``."""
    eye = np.asarray(eye, float)
    forward = np.asarray(target, float) - eye
    forward /= np.linalg.norm(forward)
    side = np.cross(forward, up)
    side /= np.linalg.norm(side)
    true_up = np.cross(side, forward)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = side, true_up, -forward
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def project_to_pixels(points_m: np.ndarray, view_proj: np.ndarray, width_px: int, height_px: int) -> np.ndarray:
    """World points (N,3) -> pixel coordinates (N,2) as (column, row) with row 0 at the TOP of the image.

    This is the convention of the renderer's read-back image, so tests can look a projected joint up."""
    pts = np.atleast_2d(np.asarray(points_m, float))
    clip = np.c_[pts, np.ones(len(pts))] @ view_proj.T
    ndc = clip[:, :2] / clip[:, 3:4]
    col = (ndc[:, 0] + 1.0) * 0.5 * width_px
    row = (1.0 - ndc[:, 1]) * 0.5 * height_px
    return np.c_[col, row]


class CameraMode(str, Enum):
    """FOLLOW keeps the orbit centred on the player; STATIC frames the whole court from behind the baseline."""

    FOLLOW = "follow"
    STATIC = "static"


@dataclass
class OrbitCamera:
    """Orbit camera around a target: yaw about +Y (0 = looking along +Z), pitch above the ground, distance.

    In FOLLOW mode the target eases towards the players' roots each frame (``follow``) so the view does not
    jitter with every step, and with several players the distance eases to one that frames them all; in STATIC
    mode the target is the court centre. The wheel's zoom scales either distance (``zoom_factor``)."""

    mode: CameraMode = CameraMode.FOLLOW
    yaw_rad: float = math.radians(-30.0)
    pitch_rad: float = math.radians(20.0)
    distance_m: float = FOLLOW_DISTANCE_M
    fovy_rad: float = math.radians(45.0)
    target_m: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, -11.0]))
    follow_gain: float = 0.2  # fraction of the remaining gap closed per frame
    zoom_factor: float = 1.0  # the operator's zoom on top of the follow distance

    STATIC_TARGET_M = np.array([0.0, 0.0, 0.0])
    STATIC_DISTANCE_M = 30.0
    STATIC_PITCH_RAD = math.radians(35.0)

    def set_mode(self, mode: CameraMode) -> None:
        self.mode = CameraMode(mode)
        if self.mode is CameraMode.STATIC:
            self.target_m = self.STATIC_TARGET_M.copy()
            self.distance_m = self.STATIC_DISTANCE_M
            self.pitch_rad = self.STATIC_PITCH_RAD
            self.yaw_rad = 0.0
        else:
            self.distance_m = FOLLOW_DISTANCE_M
            self.pitch_rad = math.radians(20.0)
        self.zoom_factor = 1.0

    def follow(self, roots_m: np.ndarray | None, aspect: float = 16 / 9) -> None:
        """Ease the orbit target towards the players' roots (3,) or (N, 3) — their centre on the ground + 1 m —
        and the distance towards one framing them all in a view of width/height ``aspect``
        (`gui.render.placement.framing_distance_m`), in FOLLOW mode."""
        if self.mode is not CameraMode.FOLLOW or roots_m is None:
            return
        goal_target, goal_distance = self._framing(roots_m, aspect)
        self.target_m = self.target_m + self.follow_gain * (goal_target - self.target_m)
        self.distance_m += self.follow_gain * (goal_distance - self.distance_m)

    def snap_to(self, roots_m: np.ndarray, aspect: float = 16 / 9) -> None:
        """Jump straight to the players (3,) or (N, 3) (first frame, a scrub, an athlete appearing) instead of
        easing; with several, in FOLLOW mode, turn to look across them (`gui.render.placement.across_yaw_rad`)."""
        yaw = across_yaw_rad(roots_m)
        if self.mode is CameraMode.FOLLOW and yaw is not None:
            # looking down a little more than on one athlete: the court between them fills the view, not the sky
            self.yaw_rad, self.pitch_rad = yaw, max(self.pitch_rad, ACROSS_PITCH_RAD)
        self.target_m, distance = self._framing(roots_m, aspect)
        if self.mode is CameraMode.FOLLOW:
            self.distance_m = distance

    def _framing(self, roots_m: np.ndarray, aspect: float) -> tuple[np.ndarray, float]:
        roots = np.asarray(roots_m, float).reshape(-1, 3)
        centre = roots.mean(axis=0)
        distance = framing_distance_m(roots, self.fovy_rad, aspect, self.yaw_rad) * self.zoom_factor
        return np.array([centre[0], 1.0, centre[2]]), distance

    def orbit(self, dyaw_rad: float, dpitch_rad: float) -> None:
        self.yaw_rad += dyaw_rad
        self.pitch_rad = float(np.clip(self.pitch_rad + dpitch_rad, math.radians(2.0), math.radians(89.0)))

    def zoom(self, factor: float) -> None:
        self.distance_m = float(np.clip(self.distance_m * factor, 1.0, 80.0))
        self.zoom_factor = float(np.clip(self.zoom_factor * factor, 0.05, 10.0))

    def right_m(self) -> np.ndarray:
        """Unit vector on the ground pointing to the right of the view (what "beside" means on screen)."""
        return np.array([-math.cos(self.yaw_rad), 0.0, math.sin(self.yaw_rad)])

    def eye_m(self) -> np.ndarray:
        cp = math.cos(self.pitch_rad)
        # the eye sits *behind* the target along the viewing direction (yaw 0 looks along +Z)
        offset = np.array([-math.sin(self.yaw_rad) * cp, math.sin(self.pitch_rad), -math.cos(self.yaw_rad) * cp])
        return self.target_m + self.distance_m * offset

    def view_proj(self, aspect: float) -> np.ndarray:
        proj = perspective(self.fovy_rad, aspect, 0.1, 200.0)
        return proj @ look_at(self.eye_m(), self.target_m)
