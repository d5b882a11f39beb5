"""Fixed-capacity numpy ring buffers for live sensor samples, and min-max decimation for drawing.

Why a ring per sensor: the console keeps the last N seconds of every stream whether or not it is on screen
(pause / zoom out / switch station must show data already received), with O(batch) appends and no
allocation in steady state."""
from __future__ import annotations

import queue
from collections.abc import Hashable

import numpy as np


class SampleRing:
    """Last ``capacity`` samples of one sensor: time (s, gateway clock) and ``channels`` values per sample."""

    def __init__(self, capacity: int, channels: int = 3) -> None:
        if capacity <= 0:
            raise ValueError("capacity must be positive")
        self.capacity = capacity
        self._t = np.zeros(capacity)
        self._v = np.zeros((capacity, channels))
        self._head = 0       # next write index
        self.count = 0       # valid samples (<= capacity)
        self.total = 0       # samples ever appended

    def append(self, t_s: np.ndarray, values: np.ndarray) -> None:
        """Append a batch (N,) times and (N, channels) values; keeps only the newest ``capacity``."""
        t_s = np.asarray(t_s, float).reshape(-1)
        n = len(t_s)
        if n == 0:
            return
        values = np.asarray(values, float).reshape(n, -1)
        self.total += n
        if n >= self.capacity:
            t_s, values, n = t_s[-self.capacity:], values[-self.capacity:], self.capacity
        idx = (self._head + np.arange(n)) % self.capacity
        self._t[idx], self._v[idx] = t_s, values
        self._head = (self._head + n) % self.capacity
        self.count = min(self.capacity, self.count + n)

    def data(self) -> tuple[np.ndarray, np.ndarray]:
        """Samples oldest first: (count,) times and (count, channels) values (copies)."""
        start = (self._head - self.count) % self.capacity
        idx = (start + np.arange(self.count)) % self.capacity
        return self._t[idx], self._v[idx]

    def latest_time(self) -> float | None:
        return float(self._t[(self._head - 1) % self.capacity]) if self.count else None


def minmax_decimate(t: np.ndarray, y: np.ndarray, max_points: int) -> tuple[np.ndarray, np.ndarray]:
    """Reduce (N,) times and (N, C) values to at most ``max_points`` rows keeping each bin's min and max.

    Peaks survive (an impact spike of one sample is still drawn), which plain striding would lose.
    Output rows alternate min/max per bin at the bin's first and last time (per channel independently)."""
    n = len(t)
    y = np.asarray(y)
    y = y.reshape(n, -1) if n else y.reshape(0, y.shape[-1] if y.ndim > 1 else 1)  # (0, C): nothing in view
    if n <= max_points or max_points < 4:
        return t, y
    bins = max_points // 2
    per = n // bins
    used = bins * per
    start = n - used  # drop the oldest remainder so the newest sample is always kept
    tb = t[start:].reshape(bins, per)
    yb = y[start:].reshape(bins, per, -1)
    t_out = np.stack([tb[:, 0], tb[:, -1]], axis=1).reshape(-1)
    y_out = np.stack([yb.min(axis=1), yb.max(axis=1)], axis=1).reshape(2 * bins, -1)
    return t_out, y_out


class TraceStore:
    """Thread-safe ingress + per-sensor rings. ``put`` from any thread; ``drain`` from the GUI thread only."""

    def __init__(self, history_s: float = 30.0, nominal_rate_hz: float = 100.0) -> None:
        self.capacity = int(history_s * nominal_rate_hz * 1.5)  # headroom for rate over nominal
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self.history_s = history_s
        self.rings: dict[Hashable, SampleRing] = {}
        # (sensor, "quat_wxyz" | "gyro_rps") -> ring, for sensors that stream orientation / angular rate
        self.channel_rings: dict[tuple[Hashable, str], SampleRing] = {}
        self._channel_queue: queue.SimpleQueue = queue.SimpleQueue()
        # (sequence number, t_s, label): numbered so a view can tell which markers it already drew; events older
        # than the history are dropped like samples, so markers never pile up over a long session
        self.events: list[tuple[int, float, str]] = []
        self._event_seq = 0

    def put(self, sensor: Hashable, t_s: np.ndarray, acc_g: np.ndarray, quat_wxyz: np.ndarray | None = None,
            gyro_rps: np.ndarray | None = None) -> None:
        """Enqueue a batch of samples for one sensor, with its orientation / angular rate when it streams them
        (any thread; never blocks)."""
        self._queue.put((sensor, t_s, acc_g))
        for name, values in (("quat_wxyz", quat_wxyz), ("gyro_rps", gyro_rps)):
            if values is not None:
                self._channel_queue.put(((sensor, name), t_s, values))

    def put_event(self, t_s: float, label: str) -> None:
        self._queue.put((None, t_s, label))

    def drain(self, max_batches: int = 5000) -> int:
        """Move queued batches into the rings (GUI thread). Bounded so one tick cannot stall the UI."""
        n = 0
        for source, rings in ((self._queue, self.rings), (self._channel_queue, self.channel_rings)):
            while n < max_batches:
                try:
                    key, t_s, payload = source.get_nowait()
                except queue.Empty:
                    break
                n += 1
                if key is None:
                    self._event_seq += 1
                    self.events.append((self._event_seq, float(t_s), str(payload)))
                    continue
                ring = rings.get(key)
                if ring is None:
                    ring = rings[key] = SampleRing(self.capacity, np.shape(payload)[-1])
                ring.append(t_s, payload)
        latest = self.latest_time()
        if latest is not None and self.events and self.events[0][1] < latest - self.history_s:
            self.events = [e for e in self.events if e[1] >= latest - self.history_s]
        return n

    def latest_time(self) -> float | None:
        times = [r.latest_time() for r in self.rings.values() if r.count]
        return max(times) if times else None
