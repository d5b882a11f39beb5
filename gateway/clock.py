"""One clock: map each base station's u32 device tick counter onto the gateway's monotonic clock (seconds).

Two steps per station:

1. `TickUnwrapper` turns u32 ticks into a continuous int64 count. It predicts where the counter should be from the
   host time elapsed since the last packet, so a wrap (counter passes 2**32 where predicted) is told apart from a
   reset (counter lands far from the prediction, e.g. back near 0 after a reboot) and from small reordering
   between sensors. A reset starts a new *epoch*: the estimator is restarted because the device time origin moved.
2. `ClockEstimator` fits ``host_arrival - device_time = offset + skew * device_time + latency`` where latency >= 0.
   Transport latency (USB batching, radio retries, scheduling) is one-sided, so the true clock relation is the
   *lower envelope* of the points (Olson 2010; TICSync / cuckoo ConvexHullOwt). Over a sliding window we keep the
   minimum per short bin, take the lower convex hull, and choose the hull edge spanning the window's mean time:
   that is the line below every point with the least total distance to them (the L1 one-sided fit), which is
   insensitive to how large or variable the latency is, unlike a least-squares fit on arrival times.

Raw ticks and arrival times are kept by the recorder, so `realign_offline` can redo the fit over a whole take.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

WRAP_TICKS = 1 << 32
SPAN_OUTLIER_FLOOR_S = 0.5e-3  # a span minimum this close to the hull line is always trusted


@dataclass
class ClockState:
    """Current estimate for one station (units in the names)."""

    offset_s: float = float("nan")  # host_time - device_time at the newest device time seen
    skew_ppm: float = 0.0  # (host rate / device rate - 1) * 1e6
    residual_s: float = float("nan")  # median height of the per-bin minima above the fitted envelope
    locked: bool = False  # warm-up over: the window spans at least `lock_after_s`
    points: int = 0  # bins in the current window
    resets: int = 0  # device resets seen (each restarts the estimator)
    wraps: int = 0  # u32 counter wraps seen

    def as_dict(self) -> dict:
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in vars(self).items()}


class TickUnwrapper:
    """u32 ticks -> int64 ticks continuous within an epoch; detects wraps and resets.

    ``tolerance_s`` bounds how far a sample may sit from the prediction (reordering across sensors, latency jitter,
    drift during a long gap) before it counts as a reset.

    Late delivery is not a reset. After a host stall (CPU starvation, a GC pause) the reader gets bytes that waited
    in the tty or in the station's buffer, stamped seconds after they were sent: behind the prediction by more than
    any fixed tolerance, then catching up within one read. So (1) the prediction is anchored on the packet that
    arrived *earliest relative to its ticks* (each packet says the counter is now at least its ticks plus the host
    time since), not on the newest one, which may itself be late; and (2) a packet between the newest value seen and
    the prediction is accepted as late. Without both, a 2 s stall split one boot into two clock epochs (seen on a
    starved 2-core machine). A reboot's counter lands in that span only by chance, and a new boot id in HELLO
    restarts the epoch anyway.
    """

    def __init__(self, tick_hz: float, tolerance_s: float = 2.0, max_drift_ppm: float = 500.0):
        self.tick_hz = float(tick_hz)
        self.tolerance_s = tolerance_s
        self.max_drift_ppm = max_drift_ppm
        self.epoch = 0
        self.wraps = 0
        self._ref: int | None = None  # newest unwrapped tick seen
        self._anchor = 0  # unwrapped ticks of the packet the prediction starts from (see the class doc) ...
        self._anchor_arrival_s = 0.0  # ... and its host arrival time

    def restart(self, tick_hz: float | None = None) -> None:
        """Forget the counter (e.g. a new boot id in HELLO): the next packet starts a new epoch."""
        if self._ref is not None:
            self.epoch += 1
        self._ref = None
        if tick_hz is not None:
            self.tick_hz = float(tick_hz)

    def unwrap(self, raw_ticks: int, arrival_s: float) -> tuple[int, bool]:
        """Unwrap one u32 tick value from a packet that arrived at host time ``arrival_s``.

        Returns (unwrapped ticks, reset?). One value per packet is enough: a batch's later samples are
        ``first + i * period`` in unwrapped ticks, so a wrap inside a batch needs no special case."""
        raw = int(raw_ticks)
        reset = False
        first = self._ref is None
        if first:
            unwrapped = raw
        else:
            elapsed_s = max(arrival_s - self._anchor_arrival_s, 0.0)
            predicted = self._anchor + int(round(elapsed_s * self.tick_hz))
            delta = (raw - predicted + WRAP_TICKS // 2) % WRAP_TICKS - WRAP_TICKS // 2
            tolerance = self.tick_hz * (self.tolerance_s + elapsed_s * self.max_drift_ppm * 1e-6)
            advance = (raw - self._ref + WRAP_TICKS // 2) % WRAP_TICKS - WRAP_TICKS // 2  # from the newest value
            if abs(delta) <= tolerance:
                unwrapped = predicted + delta
            elif predicted - self._ref < WRAP_TICKS // 2 and -tolerance <= advance <= predicted - self._ref:
                unwrapped = self._ref + advance  # delivered late
            else:
                reset = True
                self.epoch += 1
                unwrapped = raw
                self._ref = None
        if self._ref is None or unwrapped > self._ref:
            if self._ref is not None and unwrapped // WRAP_TICKS > self._ref // WRAP_TICKS:
                self.wraps += unwrapped // WRAP_TICKS - self._ref // WRAP_TICKS
            self._ref = unwrapped
        # re-anchor on a packet at or ahead of the current bound (allowing the slowest legal crystal): on time
        slowest = (arrival_s - self._anchor_arrival_s) * self.tick_hz * (1.0 - self.max_drift_ppm * 1e-6)
        if first or reset or unwrapped - self._anchor >= slowest:
            self._anchor, self._anchor_arrival_s = unwrapped, arrival_s
        return unwrapped, reset


class ClockEstimator:
    """Online lower-envelope fit of host arrival time against device time for one clock epoch.

    Feed one point per packet: the device time of the *newest* sample in it (it has the least latency) and the
    host arrival time. ``bin_s`` groups points so the hull stays small; ``window_s`` is how much history the fit
    uses (long enough to average, short enough to follow temperature drift); ``lock_after_s`` is the warm-up.
    """

    def __init__(self, window_s: float = 60.0, bin_s: float = 0.25, lock_after_s: float = 30.0):
        self.window_s = window_s
        self.bin_s = bin_s
        self.lock_after_s = lock_after_s
        self.state = ClockState()
        self._origin_s: float | None = None  # device time origin, keeps floats small
        # bin index -> (x = device time - origin, min y). A dict, not a queue: sample batches delayed on the
        # radio arrive after newer clock beacons, so points do not come in device-time order.
        self._bins: dict[int, tuple[float, float]] = {}
        self._newest_bin = -1
        self._a = 0.0  # y = a + b * x
        self._b = 0.0

    def restart(self) -> None:
        resets = self.state.resets + 1
        self.__init__(self.window_s, self.bin_s, self.lock_after_s)
        self.state.resets = resets

    def add(self, device_s: float, arrival_s: float) -> None:
        """One (device time, host arrival time) pair, both seconds, in any order."""
        if self._origin_s is None:
            self._origin_s = device_s
        x = device_s - self._origin_s
        y = arrival_s - device_s
        index = int(np.floor(x / self.bin_s))
        if index < self._newest_bin - self.window_s / self.bin_s:
            return  # older than the window
        current = self._bins.get(index)
        # lowest relative to the current skew: at large skew the raw minimum is just the bin's last point
        if current is None or y - self._b * x < current[1] - self._b * current[0]:
            self._bins[index] = (x, y)
        if index > self._newest_bin:  # time moved on by a bin: refit (a few times per second at most)
            self._newest_bin = index
            oldest = index - int(self.window_s / self.bin_s)
            for old in [k for k in self._bins if k < oldest]:
                del self._bins[old]
            self._fit()

    def _fit(self) -> None:
        pts = np.array([self._bins[k] for k in sorted(self._bins)])
        self.state.points = len(pts)
        if len(pts) < 3:  # too short for a slope: best single-point guess, no skew
            self._a, self._b = float(pts[:, 1].min()), 0.0
            self.state.offset_s = self._a
            return
        a, b = segment_envelope_line(pts[:, 0], pts[:, 1])
        self._a, self._b = a, b
        newest = pts[-1, 0]
        self.state.offset_s = float(a + b * newest)
        self.state.skew_ppm = float(b * 1e6)
        self.state.residual_s = float(np.median(pts[:, 1] - (a + b * pts[:, 0])))
        self.state.locked = bool(newest >= self.lock_after_s)

    def to_host(self, device_s: np.ndarray | float) -> np.ndarray:
        """Device time (s) -> gateway host time (s) with the current estimate."""
        if self._origin_s is None:
            raise RuntimeError("clock estimator has no points yet")
        x = np.asarray(device_s, dtype=np.float64) - self._origin_s
        return np.asarray(device_s, dtype=np.float64) + self._a + self._b * x


def segment_envelope_line(x: np.ndarray, y: np.ndarray, segments: int = 8) -> tuple[float, float]:
    """Lower-envelope line with a stable slope.

    1. Rough slope from the lower hull edge spanning mean(x) (`lower_envelope_line`).
    2. In each of ``segments`` equal spans of x, the point lowest *relative to that slope* (detrending matters:
       with 100 ppm skew, y moves 0.75 ms across a 7.5 s span, more than the latency differences we look for).
    3. Least-squares slope through those per-span minima that lie near the hull line (a span delayed as a whole
       is dropped), then the line is lowered until it touches the lowest point, so it stays below every point.
    Why not the hull edge alone: when two low points happen to lie close together, that edge's slope is wild
    (measured +-40 ppm, 2 ms at the window's end under 20 ms jitter); per-span minima spread over the whole
    window pin the slope to a few ppm. ``x`` sorted ascending."""
    a0, b0 = lower_envelope_line(x, y)
    edges = np.linspace(x[0], x[-1], segments + 1)
    span = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, segments - 1)
    starts = np.flatnonzero(np.r_[True, span[1:] != span[:-1]])
    if len(starts) < 3:
        return a0, b0
    ends = np.r_[starts[1:], len(x)]
    detrended = y - b0 * x
    lowest = np.array([s + int(np.argmin(detrended[s:e])) for s, e in zip(starts, ends)])
    # A span whose best point is far above the hull line was delayed as a whole (host starved of CPU, USB
    # stall): it says nothing about the clock, and least squares would follow it. Keep the spans near the hull.
    height = detrended[lowest] - a0
    keep = lowest[height <= max(3.0 * float(np.median(height)), SPAN_OUTLIER_FLOOR_S)]
    if len(keep) < 3:
        return a0, b0
    b = float(np.polyfit(x[keep], y[keep], 1)[0])
    a = float(np.min(y - b * x))
    return a, b


def lower_envelope_line(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Line ``y = a + b x`` below all points minimising the summed vertical gap (one-sided L1 fit).

    The optimum is the edge of the lower convex hull that spans mean(x) (maximising the line's height at the
    mean is the same objective). ``x`` must be sorted ascending; needs >= 2 distinct x."""
    hull = _lower_hull(x, y)
    xm = float(np.mean(x))
    hx, hy = x[hull], y[hull]
    k = int(np.searchsorted(hx, xm, side="right"))
    k = min(max(k, 1), len(hull) - 1)
    b = (hy[k] - hy[k - 1]) / (hx[k] - hx[k - 1])
    a = hy[k - 1] - b * hx[k - 1]
    return float(a), float(b)


def _lower_hull(x: np.ndarray, y: np.ndarray) -> list[int]:
    """Indices of the lower convex hull (Andrew's monotone chain) of points sorted by x."""
    hull: list[int] = []
    for i in range(len(x)):
        while len(hull) >= 2:
            o, a = hull[-2], hull[-1]
            cross = (x[a] - x[o]) * (y[i] - y[o]) - (y[a] - y[o]) * (x[i] - x[o])
            if cross <= 0:
                hull.pop()
            else:
                break
        if hull and x[hull[-1]] == x[i]:
            if y[i] < y[hull[-1]]:
                hull[-1] = i
            continue
        hull.append(i)
    return hull


def realign_offline(device_s: np.ndarray, arrival_s: np.ndarray, query_device_s: np.ndarray,
                    window_s: float = 60.0, bin_s: float = 0.25) -> np.ndarray:
    """Re-fit a whole take (one clock epoch) offline: host times for ``query_device_s``.

    Uses windows centred on each fit point (shifted inward at the ends of the take), fitted every ``window_s / 4``
    and linearly interpolated: no extrapolation except at the very ends, and no warm-up."""
    device_s = np.asarray(device_s, np.float64)
    arrival_s = np.asarray(arrival_s, np.float64)
    order = np.argsort(device_s)
    device_s, arrival_s = device_s[order], arrival_s[order]
    origin = device_s[0]
    x = device_s - origin
    y = arrival_s - device_s
    detrended = y - np.polyfit(x, y, 1)[0] * x  # pick bin minima relative to the overall skew
    index = np.floor(x / bin_s).astype(np.int64)
    starts = np.flatnonzero(np.r_[True, index[1:] != index[:-1]])
    ends = np.r_[starts[1:], len(y)]
    lowest = np.array([s + int(np.argmin(detrended[s:e])) for s, e in zip(starts, ends)])
    bx, by = x[lowest], y[lowest]
    centres = np.arange(0.0, x[-1] + window_s / 4, window_s / 4)
    lines = np.full((len(centres), 2), np.nan)  # (a, b) of each centre's window
    for i, c in enumerate(centres):
        lo = min(max(c - window_s / 2, 0.0), max(x[-1] - window_s, 0.0))  # keep full windows at the ends
        sel = (bx >= lo) & (bx <= lo + window_s)
        if sel.sum() >= 2:
            lines[i] = segment_envelope_line(bx[sel], by[sel])
        elif sel.any():
            lines[i] = (by[sel].min(), 0.0)
    good = np.isfinite(lines[:, 0])
    centres, lines = centres[good], lines[good]
    offsets = lines[:, 0] + lines[:, 1] * centres
    q = np.asarray(query_device_s, np.float64)
    xq = q - origin
    offset_q = np.interp(xq, centres, offsets)
    # outside the fitted centres follow the end windows' lines instead of holding the offset constant
    before, after = xq < centres[0], xq > centres[-1]
    offset_q[before] = lines[0, 0] + lines[0, 1] * xq[before]
    offset_q[after] = lines[-1, 0] + lines[-1, 1] * xq[after]
    return q + offset_q
