"""Ground-truth player trajectories in court metres for the synthetic court camera.

A :class:`PlayerPath` is sampled densely (``t_s``, position, heading, lift) and interpolated, so scripted paths and
mocap root trajectories are handled the same way. ``lift_m`` is the height of the body above its standing height
(jumps), which the camera sees as parallax and the IMU as a free-fall/impact signature (lag check).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from engine.heading import SEED_HEADING_SPEED_MPS, seed_heading_rule
from gateway.camera.court import HALF_DOUBLES_M, HALF_LENGTH_M

GRAVITY_MPS2 = 9.80665
#: Above this ground speed a player faces where they run; below it they face the net (seed rule).
RUNNING_SPEED_MPS = SEED_HEADING_SPEED_MPS


@dataclass(frozen=True)
class PlayerState:
    """Player at one instant: ground position (m), heading (rad, CONTRACTS convention), lift (m), speed (m/s)."""

    x_m: float
    y_m: float
    heading_rad: float
    lift_m: float
    speed_mps: float


@dataclass(frozen=True)
class PlayerPath:
    """Densely sampled trajectory: ``t_s`` (N,) increasing, ``xy_m`` (N, 2), ``heading_rad`` (N,), ``lift_m`` (N,)."""

    t_s: np.ndarray
    xy_m: np.ndarray
    heading_rad: np.ndarray
    lift_m: np.ndarray

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])

    def state(self, t_s: float) -> PlayerState:
        """Linear interpolation at ``t_s`` (clamped to the path's time span)."""
        x = float(np.interp(t_s, self.t_s, self.xy_m[:, 0]))
        y = float(np.interp(t_s, self.t_s, self.xy_m[:, 1]))
        heading = float(np.interp(t_s, self.t_s, self._unwrapped_heading_rad))
        lift = float(np.interp(t_s, self.t_s, self.lift_m))
        speed = float(np.interp(t_s, self.t_s, self._speed_mps))
        return PlayerState(x, y, float(np.angle(np.exp(1j * heading))), lift, speed)

    @cached_property
    def _unwrapped_heading_rad(self) -> np.ndarray:
        return np.unwrap(self.heading_rad)

    @cached_property
    def _speed_mps(self) -> np.ndarray:
        return self.speed_mps()

    def speed_mps(self) -> np.ndarray:
        """Ground speed (N,) m/s by finite differences."""
        vel = np.gradient(self.xy_m, self.t_s, axis=0)
        return np.linalg.norm(vel, axis=1)

    def vertical_acceleration_mps2(self) -> np.ndarray:
        """Second derivative (N,) of the lift: what a trunk-worn accelerometer sees on top of gravity."""
        return np.gradient(np.gradient(self.lift_m, self.t_s), self.t_s)


def rule_heading(t_s: np.ndarray, xy_m: np.ndarray) -> np.ndarray:
    """Direction of motion above :data:`RUNNING_SPEED_MPS`, else facing the net (heading = atan2(vx, vy))."""
    return seed_heading_rule(xy_m, np.gradient(xy_m, t_s, axis=0), RUNNING_SPEED_MPS)


def jump_lift_m(t_s: np.ndarray, jumps: tuple[tuple[float, float], ...], contact_s: float = 0.04) -> np.ndarray:
    """Lift (N,) m of ballistic jumps ``(take-off time s, apex height m)``, smoothed with a Gaussian of
    ``contact_s`` so push-off and landing take a finite time (finite acceleration, as a real body's)."""
    t = np.asarray(t_s, float)
    lift = np.zeros(len(t))
    for t_jump, apex_m in jumps:
        flight_s = 2.0 * np.sqrt(2.0 * apex_m / GRAVITY_MPS2)
        tau = t - t_jump
        inside = (tau >= 0) & (tau <= flight_s)
        lift[inside] = np.sqrt(2 * GRAVITY_MPS2 * apex_m) * tau[inside] - 0.5 * GRAVITY_MPS2 * tau[inside] ** 2
    if len(t) > 1 and jumps:
        from scipy.ndimage import gaussian_filter1d  # lazy: the board's gateway never synthesises jumps

        lift = gaussian_filter1d(lift, contact_s / float(np.median(np.diff(t))), mode="nearest")
    return lift


def _minimum_jerk(p0: np.ndarray, p1: np.ndarray, n: int) -> np.ndarray:
    s = np.linspace(0.0, 1.0, n, endpoint=False)[:, None]
    return p0 + (p1 - p0) * (10 * s**3 - 15 * s**4 + 6 * s**5)


def scripted_rally_path(
    duration_s: float = 12.0, *, seed: int = 0, rate_hz: float = 200.0,
    jumps: tuple[tuple[float, float], ...] = (), start_s: float = 0.0, side: str = "near",
) -> PlayerPath:
    """A rally on one half: minimum-jerk moves between random spots (baseline, wings, net approaches) at 1-4.5 m/s
    mean speed with short pauses, plus optional ``jumps`` ``(t_s, apex_height_m)`` as ballistic flights.
    ``side="far"``: the same kind of rally on the far half (point-mirrored through the court centre)."""
    if side not in ("near", "far"):
        raise ValueError(f"side must be 'near' or 'far', got {side!r}")
    rng = np.random.default_rng(seed)
    segments: list[np.ndarray] = []
    t_total = 0.0
    for segment in _rally_segments(rng, np.array([0.0, -HALF_LENGTH_M + 0.5]), rate_hz):
        segments.append(segment)
        t_total += len(segment) / rate_hz
        if t_total >= duration_s + 1.0:
            break
    xy = np.concatenate(segments)
    n = int(duration_s * rate_hz) + 1
    xy = xy[:n]
    t = start_s + np.arange(len(xy)) / rate_hz
    lift = jump_lift_m(t, jumps)
    heading = _smooth_heading(t, rule_heading(t, xy), max_rate_rad_s=8.0)
    if side == "far":
        xy, heading = -xy, heading + np.pi  # the heading rule is point-symmetric too: faces the net from there
    return PlayerPath(t, xy, heading, lift)


def _rally_segments(rng: np.random.Generator, current: np.ndarray, rate_hz: float):
    """Endless near-half rally moves from ``current``: minimum-jerk runs to random spots (baseline, wings, net
    approaches) at 1-4.5 m/s mean speed, or short pauses; each yielded segment (n, 2) starts where the last ended."""
    lo = np.array([-HALF_DOUBLES_M - 0.5, -HALF_LENGTH_M - 1.5])
    hi = np.array([HALF_DOUBLES_M + 0.5, -2.0])
    while True:
        target = rng.uniform(lo, hi)
        if rng.random() < 0.25:  # pause (split step / waiting)
            n = max(2, int(rng.uniform(0.3, 1.0) * rate_hz))
            yield np.repeat(current[None], n, axis=0)
        else:
            mean_speed = rng.uniform(1.0, 4.5)  # peak speed is 1.875x the mean
            n = max(2, int(np.linalg.norm(target - current) / mean_speed * rate_hz))
            yield _minimum_jerk(current, target, n)
            current = target


def _rally_for(rng: np.random.Generator, start_m: np.ndarray, n: int, rate_hz: float) -> np.ndarray:
    """Exactly ``n`` samples (n, 2) of rally moves from ``start_m`` on its own half (far half: point-mirrored)."""
    sign = 1.0 if start_m[1] < 0 else -1.0
    parts, total = [], 0
    for segment in _rally_segments(rng, sign * np.asarray(start_m, float), rate_hz):
        parts.append(segment)
        total += len(segment)
        if total >= n:
            break
    return sign * np.concatenate(parts)[:n]


#: Where a player who leaves the view goes: 6 m beyond the doubles sideline, outside the tracked region.
OUT_OF_VIEW_X_M = HALF_DOUBLES_M + 6.0


def changeover_rally_paths(
    crossings: int = 20, *, seed: int = 0, rate_hz: float = 200.0, leave_view_after: int | None = 5,
) -> tuple[PlayerPath, PlayerPath]:
    """Two players (first near, second far) rallying on their halves and changing ends ``crossings // 2`` times,
    so that ``crossings`` net crossings happen; the worst case for camera identity.

    Each changeover: both walk to the net at the same x (random), offset only 0.3-0.6 m to either side, and cross
    it at the same moment on minimum-jerk paths (peak speed at the net), so they pass within 0.6-1.2 m and one
    occludes the other in an oblique view. After changeover ``leave_view_after`` (None: never) the second player
    walks out 6 m past a sideline (out of the tracked region), waits 1.5 s and comes back to his half."""
    rng = np.random.default_rng(seed)
    a, b = np.array([0.0, -HALF_LENGTH_M + 0.5]), np.array([0.0, HALF_LENGTH_M - 0.5])
    parts_a: list[np.ndarray] = []
    parts_b: list[np.ndarray] = []

    def move(to_a: np.ndarray, to_b: np.ndarray, seconds: float) -> None:
        nonlocal a, b
        n = max(2, int(seconds * rate_hz))
        parts_a.append(_minimum_jerk(a, to_a, n))
        parts_b.append(_minimum_jerk(b, to_b, n))
        a, b = to_a, to_b

    for k in range(crossings // 2):
        n = int(rng.uniform(1.0, 2.0) * rate_hz)
        parts_a.append(_rally_for(rng, a, n, rate_hz))
        parts_b.append(_rally_for(rng, b, n, rate_hz))
        a, b = parts_a[-1][-1], parts_b[-1][-1]
        x, offset = rng.uniform(-3.0, 3.0), rng.uniform(0.3, 0.6) * rng.choice([-1.0, 1.0])
        ya = -2.5 if a[1] < 0 else 2.5
        start_a, start_b = np.array([x + offset, ya]), np.array([x - offset, -ya])
        move(start_a, start_b, max(np.linalg.norm(start_a - a), np.linalg.norm(start_b - b)) / 3.0 + 0.2)
        move(start_a * [1, -1], start_b * [1, -1], 5.0 / rng.uniform(1.5, 3.0))
        if leave_view_after is not None and k + 1 == leave_view_after:
            home = b.copy()
            out = np.array([OUT_OF_VIEW_X_M, b[1]])
            move(a, out, 2.5)
            move(a, out, 1.5)
            move(a, home, 2.5)
    n = int(1.0 * rate_hz)
    parts_a.append(_rally_for(rng, a, n, rate_hz))
    parts_b.append(_rally_for(rng, b, n, rate_hz))
    t = np.arange(sum(len(p) for p in parts_a)) / rate_hz
    return tuple(PlayerPath(t, xy, _smooth_heading(t, rule_heading(t, xy), max_rate_rad_s=8.0), np.zeros(len(t)))
                 for xy in (np.concatenate(parts_a), np.concatenate(parts_b)))  # type: ignore[return-value]


def _smooth_heading(t_s: np.ndarray, heading_rad: np.ndarray, max_rate_rad_s: float) -> np.ndarray:
    """Rate-limit heading changes (a body cannot snap 180 degrees in one sample); sequential by nature."""
    out = np.empty_like(heading_rad)
    out[0] = heading_rad[0]
    dt = np.diff(t_s, prepend=t_s[0])
    for i in range(1, len(out)):
        delta = np.angle(np.exp(1j * (heading_rad[i] - out[i - 1])))
        step = max_rate_rad_s * dt[i]
        out[i] = out[i - 1] + np.clip(delta, -step, step)
    return np.angle(np.exp(1j * out))
