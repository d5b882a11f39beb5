"""Resample asynchronous per-sensor sample streams onto one uniform frame clock (the motion graph's rate).

Why: each sensor arrives in its own batches with its own jitter and occasional gaps, but the synthesizer
needs one (S, 3) acceleration frame per graph frame. A frame at time t is emitted only once every sensor
has a sample at or after t, so no frame is ever extrapolated; values are linearly interpolated."""
from __future__ import annotations

from collections.abc import Hashable, Sequence

import numpy as np


class FrameResampler:
    """Feed batches per sensor; pull complete uniform frames ``(t_s, acc_g (S, 3))``."""

    def __init__(self, sensors: Sequence[Hashable], rate_hz: float) -> None:
        self.sensors = list(sensors)
        self.period_s = 1.0 / rate_hz
        self._t: dict[Hashable, np.ndarray] = {s: np.zeros(0) for s in self.sensors}
        self._v: dict[Hashable, np.ndarray] = {s: np.zeros((0, 3)) for s in self.sensors}
        self._next_t: float | None = None
        self.frames_out = 0

    def add(self, sensor: Hashable, t_s: np.ndarray, acc_g: np.ndarray) -> None:
        """Append a batch (ignored for sensors not in the list). Times must increase per sensor."""
        if sensor not in self._t:
            return
        t_s = np.asarray(t_s, float).reshape(-1)
        keep = t_s > (self._t[sensor][-1] if len(self._t[sensor]) else -np.inf)  # drop duplicates/out-of-order
        self._t[sensor] = np.concatenate([self._t[sensor], t_s[keep]])
        self._v[sensor] = np.concatenate([self._v[sensor], np.asarray(acc_g, float).reshape(-1, 3)[keep]])

    def frames(self) -> tuple[np.ndarray, np.ndarray]:
        """All newly complete frames: times (F,) and accelerations (F, S, 3); trims consumed history."""
        if any(len(t) == 0 for t in self._t.values()):
            return np.zeros(0), np.zeros((0, len(self.sensors), 3))
        start = max(t[0] for t in self._t.values())
        end = min(t[-1] for t in self._t.values())
        if self._next_t is None:
            self._next_t = np.ceil(start / self.period_s) * self.period_s
        if end < self._next_t:
            return np.zeros(0), np.zeros((0, len(self.sensors), 3))
        n = int(np.floor((end - self._next_t) / self.period_s + 1e-9)) + 1
        times = self._next_t + self.period_s * np.arange(n)
        out = np.empty((n, len(self.sensors), 3))
        for k, s in enumerate(self.sensors):
            t, v = self._t[s], self._v[s]
            for c in range(3):
                out[:, k, c] = np.interp(times, t, v[:, c])
            # keep one sample at or before the next frame time so interpolation stays bracketed
            cut = max(0, int(np.searchsorted(t, times[-1], side="right")) - 1)
            self._t[s], self._v[s] = t[cut:], v[cut:]
        self._next_t = float(times[-1] + self.period_s)
        self.frames_out += n
        return times, out
