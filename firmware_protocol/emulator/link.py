"""A thread-safe handle on one emulated station, shared by every transport (pty, emu:// URL, fake HID).

Time is either driven by the caller (`advance(seconds)`, deterministic tests) or by the wall clock: in
real-time mode every `take()` first advances the station by the wall time elapsed since the last call, times
`speed`. Catching up lazily on demand is exact (the station's output does not depend on how time is chunked),
so the URL and HID transports need no thread at all.
"""
from __future__ import annotations

import threading
import time

from .station import BaseStation


class EmulatorLink:
    def __init__(self, station: BaseStation, realtime: bool = False, speed: float = 1.0) -> None:
        if speed <= 0:
            raise ValueError(f"speed must be > 0, got {speed}")
        self.station = station
        self.realtime = realtime
        self.speed = speed
        self._lock = threading.Lock()
        self._outbox = bytearray()
        self._wall_s = time.monotonic()
        self.wall_origin_s = self._wall_s     # time.monotonic() at emulated time 0 (real-time mode)
        self.bytes_taken = 0                  # stream offset of the next byte take() will return

    def advance(self, seconds: float) -> None:
        """Manual time: run the station `seconds` forward; its output waits in the outbox."""
        with self._lock:
            self._outbox += self.station.advance(seconds)

    def _catch_up(self) -> None:
        now = time.monotonic()
        elapsed, self._wall_s = now - self._wall_s, now
        self._outbox += self.station.advance(elapsed * self.speed)

    def true_to_monotonic(self, t_true_s: float) -> float:
        """Host `time.monotonic()` at which real-time emulation reaches true time `t_true_s`."""
        return self.wall_origin_s + t_true_s / self.speed

    def take(self, max_bytes: int | None = None) -> bytes:
        """Station->host bytes available now (at most `max_bytes`)."""
        with self._lock:
            if self.realtime:
                self._catch_up()
            n = len(self._outbox) if max_bytes is None else min(max_bytes, len(self._outbox))
            data = bytes(self._outbox[:n])
            del self._outbox[:n]
            self.bytes_taken += n
            return data

    def pending(self) -> int:
        with self._lock:
            if self.realtime:
                self._catch_up()
            return len(self._outbox)

    def write(self, data: bytes) -> None:
        """Host->station bytes. In real time the station first catches up, so replies (e.g. a round-trip
        CLOCK_SYNC) carry the station time of the moment the command arrived."""
        with self._lock:
            if self.realtime:
                self._catch_up()
            self.station.write(data)

    def discard(self, start: int, end: int) -> None:
        """The transport threw away taken bytes [start, end) (e.g. no host attached): keep ground truth honest."""
        with self._lock:
            self.station.lose_output(start, end)

    def unplug(self, bytes_delivered: int | None = None) -> None:
        """Pull the cable. `bytes_delivered` defaults to everything taken so far (the transport had no queue)."""
        with self._lock:
            self.station.unplug(self.bytes_taken if bytes_delivered is None else bytes_delivered)
            self.bytes_taken = self.station.bytes_out
            self._outbox.clear()

    def replug(self) -> None:
        with self._lock:
            if self.realtime:
                self._catch_up()                 # time passed while unplugged
            self.station.replug()
