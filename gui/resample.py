"""Resample asynchronous per-sensor sample streams onto one uniform frame clock (the motion graph's rate).

Why: each sensor arrives in its own batches with its own jitter and occasional gaps, but the synthesizer
needs one (S, 3) acceleration frame per graph frame. A frame at time t is the mean of the linearly interpolated
signal over one frame period centred on t: an anti-alias box filter before decimating (100 Hz -> 30 Hz would
otherwise fold 15-50 Hz content into the band, as plain point sampling does), exact for any linear stretch of
signal whatever the sample times, and close to what the graph's virtual sensors saw (accelerations of 30 Hz
mocap). A frame is emitted once every live sensor has samples past its window, so nothing is extrapolated.

A sensor that falls silent must not freeze synthesis: once it is more than ``max_gap_s`` behind the newest
sensor it stops holding frames back, and every frame whose bracketing samples (for any sensor) are more than
``max_gap_s`` apart is marked invalid — the caller then steps the search on the camera alone instead of
feeding made-up accelerations."""
from __future__ import annotations

from collections.abc import Hashable, Sequence

import numpy as np


class FrameResampler:
    """Feed batches per sensor; pull uniform frames ``(t_s (F,), acc_g (F, S, 3), valid (F,))``."""

    def __init__(self, sensors: Sequence[Hashable], rate_hz: float, max_gap_s: float = 0.25) -> None:
        if max_gap_s < 1.0 / rate_hz:
            raise ValueError(f"max_gap_s {max_gap_s} must be at least one frame period ({1.0 / rate_hz:.4f} s)")
        self.sensors = list(sensors)
        self.period_s = 1.0 / rate_hz
        self.max_gap_s = max_gap_s
        self._t: dict[Hashable, np.ndarray] = {s: np.zeros(0) for s in self.sensors}
        self._v: dict[Hashable, np.ndarray] = {s: np.zeros((0, 3)) for s in self.sensors}
        self._next_t: float | None = None
        self.frames_out = 0
        self.frames_invalid = 0

    def add(self, sensor: Hashable, t_s: np.ndarray, acc_g: np.ndarray) -> None:
        """Append a batch (ignored for sensors not in the list). Times must increase per sensor."""
        if sensor not in self._t:
            return
        t_s = np.asarray(t_s, float).reshape(-1)
        keep = t_s > (self._t[sensor][-1] if len(self._t[sensor]) else -np.inf)  # drop duplicates/out-of-order
        self._t[sensor] = np.concatenate([self._t[sensor], t_s[keep]])
        self._v[sensor] = np.concatenate([self._v[sensor], np.asarray(acc_g, float).reshape(-1, 3)[keep]])

    def _empty(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return np.zeros(0), np.zeros((0, len(self.sensors), 3)), np.zeros(0, bool)

    def frames(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All newly available frames: times (F,), accelerations (F, S, 3) and validity (F,); trims history."""
        if any(len(t) == 0 for t in self._t.values()):  # every worn sensor must have spoken once
            return self._empty()
        half = self.period_s / 2
        lasts = np.array([t[-1] for t in self._t.values()])
        live = lasts >= lasts.max() - self.max_gap_s
        end = lasts[live].min() - half  # the last frame whose whole window every live sensor has covered
        if self._next_t is None:  # first frame whose whole window lies after every sensor's first sample
            start = max(t[0] for t in self._t.values()) + half
            self._next_t = np.ceil(start / self.period_s - 1e-9) * self.period_s
        if end < self._next_t:
            return self._empty()
        n = int(np.floor((end - self._next_t) / self.period_s + 1e-9)) + 1
        times = self._next_t + self.period_s * np.arange(n)
        out = np.empty((n, len(self.sensors), 3))
        valid = np.ones(n, bool)
        for k, s in enumerate(self.sensors):
            t, v = self._t[s], self._v[s]
            out[:, k] = box_mean(t, v, times - half, times + half)
            valid &= window_covered(t, times - half, times + half, self.max_gap_s)
            # keep from the sample at or before the next frame's window start, so it stays bracketed
            cut = max(0, int(np.searchsorted(t, times[-1] + self.period_s - half, side="right")) - 1)
            self._t[s], self._v[s] = t[cut:], v[cut:]
        self._next_t = float(times[-1] + self.period_s)
        self.frames_out += n
        self.frames_invalid += int((~valid).sum())
        return times, out, valid


def box_mean(t: np.ndarray, v: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Mean of the piecewise-linear interpolant of samples ``v`` (N, C) at ``t`` (N,) over each window
    [lo, hi] (F,), windows clipped to the sampled span; a window of zero length gives the interpolated value.

    Vectorised through the cumulative trapezoid integral F: F(x) = F(t_i) + v_i d + slope_i d^2 / 2, d = x - t_i."""
    v = np.asarray(v, float).reshape(len(t), -1)
    lo, hi = np.clip(lo, t[0], t[-1]), np.clip(hi, t[0], t[-1])
    if len(t) < 2:
        return np.repeat(v[:1], len(lo), axis=0)
    dt = np.diff(t)
    slope = np.diff(v, axis=0) / dt[:, None]
    cum = np.concatenate([np.zeros((1, v.shape[1])), np.cumsum(0.5 * (v[1:] + v[:-1]) * dt[:, None], axis=0)])

    def integral_to(x: np.ndarray) -> np.ndarray:
        i = np.clip(np.searchsorted(t, x, side="right") - 1, 0, len(t) - 2)
        d = (x - t[i])[:, None]
        return cum[i] + v[i] * d + 0.5 * slope[i] * d * d

    width = (hi - lo)[:, None]
    point = np.stack([np.interp(lo, t, v[:, c]) for c in range(v.shape[1])], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (integral_to(hi) - integral_to(lo)) / width
    return np.where(width > 1e-12, mean, point)


def window_covered(t: np.ndarray, lo: np.ndarray, hi: np.ndarray, max_gap_s: float, tol_s: float = 1e-9) -> np.ndarray:
    """(F,) True where samples span each window [lo, hi] with no gap longer than ``max_gap_s`` touching it.

    A gap longer than the window cannot lie strictly inside it, so checking the sample intervals that contain
    ``lo`` and ``hi`` is enough (the caller guarantees max_gap_s >= window length)."""
    covered = (t[0] <= lo + tol_s) & (t[-1] >= hi - tol_s)
    if len(t) < 2:
        return covered & (hi - lo <= tol_s)
    i_lo = np.clip(np.searchsorted(t, lo + tol_s, side="right") - 1, 0, len(t) - 2)  # t[i] <= lo < t[i+1]
    i_hi = np.clip(np.searchsorted(t, hi - tol_s, side="left") - 1, 0, len(t) - 2)   # t[i] < hi <= t[i+1]
    dt = np.diff(t)
    return covered & (dt[i_lo] <= max_gap_s) & (dt[i_hi] <= max_gap_s)
