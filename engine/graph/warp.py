"""Root warping: the pose comes from the database, the path from the camera (issue 11).

A motion graph holds only the turns and speeds its clips hold; a take that turns at 140 deg/s through a graph whose
clips never turn more than 16 deg in a second drifts off the camera track by metres, and a strong position/heading
cost then makes the search pick wrong motions that happen to turn. So after every sample each path's carried
root (eq. 5 of seed 000) is pulled towards the camera fix:

    P <- P + min(g_P |M - P|, v_max dt) (M - P) / |M - P|,    O <- O + clip(g_O wrap(M_h - O), +-w_max dt)

a complementary filter: the path's own per-frame motion (what the database knows: the step's sway, the speed of a
stride) passes through, the camera's absolute position and heading win over a few frames (time constant ~1/(g fps)),
and the correction per frame is bounded by what a body can do (v_max, w_max: a sprint, a fast pivot), so a single
wild camera fix cannot teleport the skeleton. The search's position / heading costs still compare each edge's
*prediction* (before the warp) with the fix, so they score how well the motion explains the camera's
displacement over the last ~1/g frames rather than an error that grows without bound.

g = 0 (the library default, `RootWarp.off()`) is seed 000's search exactly. The output root of the chosen path
is the same recursion replayed along it (`ViterbiLattice.global_states`), so batch and fixed-lag agree.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import wrap_angle


@dataclass(frozen=True)
class RootWarp:
    """Gains (0..1 per sample) and per-second bounds of the pull towards the camera (see module doc).

    Defaults measured on chained held-out Bandai takes with a 5 cm / 10 deg camera (docs/engine-graph.md):
    position gain 0.5 and heading gain 0.25 (0.3 / 0.7 and 0.4 tried) halve the camera's per-frame noise while
    a turn the graph lacks lags by w (1 - g) / g (a 140 deg/s turn: 14 deg while it lasts). Bounds: 8 m/s of
    correction (faster than any court sprint needs on top of the path's own motion) and 6 rad/s (~340 deg/s,
    a fast pivot)."""

    position_gain: float = 0.5
    heading_gain: float = 0.25
    max_speed_mps: float = 8.0
    max_turn_rps: float = 6.0

    @classmethod
    def off(cls) -> "RootWarp":
        return cls(0.0, 0.0, 0.0, 0.0)

    @property
    def active(self) -> bool:
        return self.position_gain > 0 or self.heading_gain > 0

    def per_sample(self, fps: float) -> tuple[np.float32, np.float32, np.float32, np.float32]:
        """(g_P, max metres, g_O, max radians) per sample as float32 (the search's state precision)."""
        return (np.float32(self.position_gain), np.float32(self.max_speed_mps / fps),
                np.float32(self.heading_gain), np.float32(self.max_turn_rps / fps))


def warp_one(ground_m: complex, heading_rad: float, fix_m: complex | None, fix_heading_rad: float | None,
             warp: RootWarp, fps: float) -> tuple[complex, float]:
    """The same pull for one root in float64 (the output replay, OLNG and the HMM use it)."""
    if fix_m is not None and warp.position_gain > 0:
        err = fix_m - ground_m
        d = abs(err)
        if d > 0:
            ground_m += err * min(warp.position_gain * d, warp.max_speed_mps / fps) / d
    if fix_heading_rad is not None and warp.heading_gain > 0:
        lim = warp.max_turn_rps / fps
        heading_rad = float(wrap_angle(heading_rad + np.clip(
            warp.heading_gain * wrap_angle(fix_heading_rad - heading_rad), -lim, lim)))
    return ground_m, heading_rad


def follow_camera(steps_local_m: np.ndarray, dheading_rad: np.ndarray, start: tuple[complex, float],
                  fix_m: np.ndarray | None, fix_heading_rad: np.ndarray | None, warp: RootWarp, fps: float,
                  reset: np.ndarray | None = None, heading_offset_rad: np.ndarray | float = 0.0,
                  step_first: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """A root path integrated from per-frame steps (ground step (T, 2) in the previous frame's heading frame, and
    heading change (T,)) and warped towards camera fixes (T, 2) / (T,) (NaN = no fix) after every frame.

    `start` is the state at frame 0 (no step into it) unless `step_first`. `reset` (T,) bool: put the root on that
    frame's fix instead of pulling (a take's first fix). `heading_offset_rad`: the body's heading minus the
    integrated one, per frame or constant -- for reconstructors whose integrated yaw is the root joint's twist
    while the camera reports where the body faces. Returns ground (T, 2) and heading (T,) (wrapped)."""
    n = len(dheading_rad)
    ground, heading = complex(start[0]), float(start[1])
    out_g = np.empty(n, dtype=complex)
    out_h = np.empty(n)
    offset = np.broadcast_to(np.asarray(heading_offset_rad, float), (n,))
    for i in range(n):
        if i > 0 or step_first:
            ground += complex(steps_local_m[i, 0], steps_local_m[i, 1]) * np.exp(-1j * heading)
            heading += dheading_rad[i]
        pos = None if fix_m is None or np.any(np.isnan(fix_m[i])) else complex(fix_m[i, 0], fix_m[i, 1])
        head = None if fix_heading_rad is None or np.isnan(fix_heading_rad[i]) else float(fix_heading_rad[i])
        if reset is not None and reset[i]:
            ground = pos if pos is not None else ground
            heading = head - offset[i] if head is not None else heading
        else:
            ground, body = warp_one(ground, heading + offset[i], pos, head, warp, fps)
            heading = body - offset[i]
        out_g[i], out_h[i] = ground, heading
    return np.stack([out_g.real, out_g.imag], axis=1), wrap_angle(out_h)
