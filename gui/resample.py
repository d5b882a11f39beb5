"""Resample asynchronous per-sensor sample streams onto one uniform frame clock (the motion graph's rate).

Why: each sensor arrives in its own batches with its own jitter and occasional gaps, but the synthesizer
needs one (S, 3) acceleration frame per graph frame. A frame at time t is emitted once every live sensor has
a sample at or after t, so no frame is ever extrapolated; values are linearly interpolated.

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
        lasts = np.array([t[-1] for t in self._t.values()])
        live = lasts >= lasts.max() - self.max_gap_s
        end = lasts[live].min()
        if self._next_t is None:
            start = max(t[0] for t in self._t.values())
            self._next_t = np.ceil(start / self.period_s) * self.period_s
        if end < self._next_t:
            return self._empty()
        n = int(np.floor((end - self._next_t) / self.period_s + 1e-9)) + 1
        times = self._next_t + self.period_s * np.arange(n)
        out = np.empty((n, len(self.sensors), 3))
        valid = np.ones(n, bool)
        for k, s in enumerate(self.sensors):
            t, v = self._t[s], self._v[s]
            for c in range(3):
                out[:, k, c] = np.interp(times, t, v[:, c])
            # first sample at or after each frame (1 ns tolerance: frame times are sums of float periods)
            after = np.searchsorted(t, times - 1e-9, side="left")
            before = np.clip(after - 1, 0, len(t) - 1)
            next_t = np.where(after < len(t), t[np.minimum(after, len(t) - 1)], np.inf)
            at_sample = np.abs(next_t - times) <= 1e-9
            valid &= at_sample | (next_t - t[before] <= self.max_gap_s)
            # keep one sample at or before the last frame time so the next frames stay bracketed
            cut = max(0, int(np.searchsorted(t, times[-1], side="right")) - 1)
            self._t[s], self._v[s] = t[cut:], v[cut:]
        self._next_t = float(times[-1] + self.period_s)
        self.frames_out += n
        self.frames_invalid += int((~valid).sum())
        return times, out, valid
