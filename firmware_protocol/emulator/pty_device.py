"""The part every vendor-device emulator shares: a raw pty the vendor's library opens as the device's serial port,
two daemon threads (one streams, one answers commands), and a clean stop.

Why one base: the x-IMU3 and Shimmer3 emulators differ only in the bytes they speak; their pty and thread
lifecycle must behave identically (a closed pty stops both threads, stop() joins and closes both ends)."""
from __future__ import annotations

import os
import pty
import threading
import tty
from typing import Callable, TypeVar

Self = TypeVar("Self", bound="PtyDeviceEmulator")


class PtyDeviceEmulator:
    """Owns the pty pair (`path` is the slave's device path) and the emulator threads."""

    def __init__(self, *targets: Callable[[], None]) -> None:
        # None: the replayed readings start over whenever streaming starts. A host monotonic time: they follow
        # that origin instead (the row played at host time t is the one at t - origin_s; before it, the first),
        # so several devices worn by one subject replay one motion in step, and a test can start it on cue.
        self.origin_s: float | None = None
        self._master, self._slave = pty.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._write_lock = threading.Lock()
        self._threads = [threading.Thread(target=t, daemon=True) for t in targets]

    def start(self: Self) -> Self:
        for t in self._threads:
            t.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(2.0)
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self: Self) -> Self:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def _replay_row(self, k: int, host_s: float, rate_hz: float, n_rows: int) -> int:
        """Which of ``n_rows`` replayed readings sample ``k`` (due at ``host_s``) carries (see ``origin_s``)."""
        if self.origin_s is None:
            return k % n_rows
        return max(0, int(round((host_s - self.origin_s) * rate_hz))) % n_rows

    def _write(self, data: bytes) -> None:
        """Bytes to the host; a closed pty (the host went away) stops the emulator."""
        with self._write_lock:
            try:
                os.write(self._master, data)
            except OSError:
                self._stop.set()
