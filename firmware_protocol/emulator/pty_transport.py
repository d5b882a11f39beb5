"""Pseudo-terminal transport: the host opens `slave_path` with pyserial exactly like /dev/ttyACM0.

One I/O thread per station moves bytes between the pty master and the EmulatorLink (commands in, frames out).
Like a USB CDC device whose port is closed (DTR low), the station's output is dropped while no host has the
slave open; the ground truth marks those frames lost. `unplug()` closes the master, which the host sees as
a disconnected device (pyserial raises SerialException); `replug()` creates a fresh pty (a new /dev/pts/N,
as a real replug may get a new ttyACM number) and, if `symlink` was given, repoints that stable path to it.
"""
from __future__ import annotations

import fcntl
import os
import pty
import select
import termios
import threading
import time
import tty
from pathlib import Path

from .link import EmulatorLink

_CHUNK = 4096
_IDLE_POLL_MS = 2
UNPLUG_DRAIN_S = 0.5


class PtyTransport:
    def __init__(self, link: EmulatorLink, symlink: str | Path | None = None) -> None:
        self.link = link
        self.symlink = Path(symlink) if symlink else None
        self.bytes_written = 0                # to the master, i.e. into the host's tty input queue
        self.bytes_dropped_no_host = 0
        self._master = -1
        self.slave_path = ""
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._unsent = b""
        self._open_pty()

    # ------------------------------------------------------------------ lifecycle
    def _open_pty(self) -> None:
        master, slave = pty.openpty()
        tty.setraw(slave)                     # canonical mode would hold bytes until a newline
        self.slave_path = os.ttyname(slave)
        os.close(slave)                       # we are the device side: only the host keeps the slave open
        os.set_blocking(master, False)
        self._master = master
        self._unsent = b""
        if self.symlink is not None:
            tmp = self.symlink.with_name(self.symlink.name + ".tmp")
            tmp.unlink(missing_ok=True)
            tmp.symlink_to(self.slave_path)
            tmp.replace(self.symlink)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"pty-{self.slave_path}", daemon=True)
        self._thread.start()

    def _stop_thread(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    def _unread_by_host(self) -> int:
        """Bytes still waiting in the host's tty input queue (lost if the master closes now)."""
        try:
            fd = os.open(self.slave_path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError:
            return 0
        try:
            return int.from_bytes(fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"), "little")
        finally:
            os.close(fd)

    def unplug(self) -> None:
        """Pull the cable: the host's port dies. Frames still queued in the emulator are lost; bytes already in
        the host's tty buffer get up to `UNPLUG_DRAIN_S` to be read first, so that the ground truth is exact for
        a host that reads promptly (the kernel moves pty bytes through a flip buffer that FIONREAD cannot see,
        so counting "unread" bytes at an arbitrary instant would be racy)."""
        if self._master < 0:
            return
        self._stop_thread()
        deadline = time.monotonic() + UNPLUG_DRAIN_S
        time.sleep(0.005)                     # let the flip buffer reach the line discipline
        while (unread := self._unread_by_host()) and time.monotonic() < deadline:
            time.sleep(0.002)
        delivered = self.link.bytes_taken - len(self._unsent) - unread
        os.close(self._master)
        self._master = -1
        self.link.unplug(bytes_delivered=delivered)

    def replug(self) -> None:
        if self._master >= 0:
            return
        self.link.replug()
        self._open_pty()

    def close(self) -> None:
        self._stop_thread()
        if self._master >= 0:
            os.close(self._master)
            self._master = -1
        if self.symlink is not None and self.symlink.is_symlink():
            self.symlink.unlink()

    def __enter__(self) -> PtyTransport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ I/O thread
    def _run(self) -> None:
        poller = select.poll()
        fd = self._master
        while not self._stop.is_set():
            if not self._unsent:
                self._unsent = self.link.take(_CHUNK * 4)
            poller.register(fd, select.POLLIN | (select.POLLOUT if self._unsent else 0))
            events = poller.poll(_IDLE_POLL_MS if not self._unsent else 50)
            poller.unregister(fd)
            mask = events[0][1] if events else 0
            if mask & select.POLLHUP:
                self._drop_unsent()          # nobody has the port open
                self._stop.wait(_IDLE_POLL_MS / 1000)
                continue
            if mask & select.POLLIN:
                try:
                    data = os.read(fd, _CHUNK)
                except (BlockingIOError, OSError):
                    data = b""
                if data:
                    self.link.write(data)
            if mask & select.POLLOUT and self._unsent:
                try:
                    n = os.write(fd, self._unsent[:_CHUNK])
                except (BlockingIOError, OSError):
                    n = 0
                self._unsent = self._unsent[n:]
                self.bytes_written += n

    def _drop_unsent(self) -> None:
        if self._unsent:
            end = self.link.bytes_taken
            self.link.discard(end - len(self._unsent), end)
            self.bytes_dropped_no_host += len(self._unsent)
            self._unsent = b""
