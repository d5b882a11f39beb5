"""Per-sensor still/movement statistics and tap detection on raw accelerometer samples (g).

Why both ``std(|a|)`` and per-axis std for stillness: ``|a|`` is insensitive to slow rotation (a sensor turning
in place keeps |a| = 1 g) while the per-axis std catches it; together they gate a static pose.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter


@dataclass(frozen=True)
class Stillness:
    """Statistics of a window: ``norm_std_g`` = std of |a|, ``axis_std_g`` = largest per-axis std, ``span_s``."""

    norm_std_g: float
    axis_std_g: float
    span_s: float

    @property
    def worst_g(self) -> float:
        return max(self.norm_std_g, self.axis_std_g)

    def meter(self, threshold_g: float) -> float:
        """Console stillness meter: 1 when under the threshold, falling linearly to 0 at twice it."""
        return float(np.clip(2.0 - self.worst_g / threshold_g, 0.0, 1.0))


def stillness(t_s: np.ndarray, acc_g: np.ndarray) -> Stillness:
    """Stillness statistics of samples ``acc_g`` (N, 3) at ``t_s`` (N,)."""
    if len(t_s) < 2:
        return Stillness(np.inf, np.inf, 0.0)
    acc = np.asarray(acc_g, float)
    return Stillness(float(np.linalg.norm(acc, axis=1).std()), float(acc.std(axis=0).max()), float(t_s[-1] - t_s[0]))


@dataclass(frozen=True)
class TapEvent:
    """A tap: peak time ``t_s`` (sub-sample, parabolic), peak height ``peak_g`` above the baseline |a|."""

    t_s: float
    peak_g: float


def detect_tap(t_s: np.ndarray, acc_g: np.ndarray, threshold_g: float = 1.0, baseline_s: float = 0.5,
               settle_s: float = 0.05) -> TapEvent | None:
    """First sharp spike of |a| over a rolling-median baseline (the tapped sensor's impact).

    The event is the highest sample of the first run above ``threshold_g``, refined by a parabola through it
    and its neighbours; it is reported only once ``settle_s`` of data follows the run (the peak is complete)."""
    t = np.asarray(t_s, float)
    if len(t) < 5:
        return None
    magnitude = np.linalg.norm(np.asarray(acc_g, float), axis=1)
    rate = 1.0 / float(np.median(np.diff(t)))
    baseline = median_filter(magnitude, size=max(3, int(baseline_s * rate) | 1), mode="nearest")
    high = magnitude - baseline
    above = np.flatnonzero(high > threshold_g)
    if len(above) == 0:
        return None
    start = above[0]
    end = start
    while end + 1 < len(high) and high[end + 1] > threshold_g:
        end += 1
    if t[-1] - t[end] < settle_s:
        return None
    k = start + int(np.argmax(high[start : end + 1]))
    offset = 0.0
    if 0 < k < len(high) - 1:
        a, b, c = high[k - 1], high[k], high[k + 1]
        denom = a - 2 * b + c
        offset = float(np.clip(0.5 * (a - c) / denom, -0.5, 0.5)) if denom < 0 else 0.0
    t_peak = t[k] + offset * (t[k + 1] - t[k] if offset > 0 else t[k] - t[k - 1])
    return TapEvent(float(t_peak), float(high[k]))
