"""Pseudo-terminal transport: the host opens `slave_path` with pyserial exactly like /dev/ttyACM0.

One I/O thread per station moves bytes between the pty master and the EmulatorLink (commands in, frames out).
Like a USB CDC device whose port is closed (DTR low), the station's output is dropped while no host has the
slave open; the ground truth marks those frames lost. `unplug()` closes the master, which the host sees as
a disconnected device (pyserial raises SerialException) and removes the stable `symlink` as udev removes a
/dev/serial/by-id path (else a host retrying it would open whatever device gets that /dev/pts/N next);
`replug()` creates a fresh pty (a new /dev/pts/N, as a real replug may get a new ttyACM number) and, if
`symlink` was given, points that stable path to it again.

Exact ground truth at an unplug. Bytes written to the master are not yet the host's: Linux first queues them in
the slave's flip buffer, a kernel worker moves them into the line discipline's read buffer (at most 4095 bytes;
the rest waits in the flip buffer), and closing the master hangs the slave up, which discards both. FIONREAD
on the slave counts only the read buffer, so "unread" cannot be measured from outside at an arbitrary instant.
Two kernel behaviours make it exact instead (checked on a pty pair, also under CPU load): when the read buffer
is empty, poll() and read() on the slave first wait for the flip worker (`tty_buffer_flush_work`); and every byte
goes to exactly one read(). So `unplug()` stops writing, gives the host `UNPLUG_DRAIN_S` to read everything
(FIONREAD == 0 and poll() then reports nothing: no byte is left anywhere), and otherwise reads whatever the host
did not from its own descriptor on the slave. Those bytes are the ones the cable pull destroys; their frames are
marked LOST_UNPLUGGED and every other written frame really reached the host. If the host happened to read while
the transport was collecting, the collected chunks are holes in the host's stream rather than its tail; they are
located by content in the recently written bytes (frames carry seq numbers and CRCs, so chunks are unambiguous
in practice) and the frame the host's decoder then merges across a hole is marked lost too.
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
UNPLUG_DRAIN_S = 0.5                  # how long a host gets to read what is already in its tty at an unplug
_RECENT_BYTES = 1 << 16               # written bytes kept for locating holes (a pty holds < 16 KiB unread)


class PtyTransport:
    def __init__(self, link: EmulatorLink, symlink: str | Path | None = None) -> None:
        self.link = link
        self.symlink = Path(symlink) if symlink else None
        self.bytes_written = 0                # to the master, i.e. into the host's tty input queue
        self.bytes_dropped_no_host = 0
        self.bytes_lost_at_unplug = 0         # written to the master but never read by the host (all unplugs)
        self.last_unplug_holes: list[tuple[int, int]] = []  # stream ranges the host never read, last unplug
        self._master = -1
        self.slave_path = ""
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._unsent = b""
        # Bytes written to this pty, in the order the host reads them ("written" positions), for unplug():
        self._written = 0
        self._recent = bytearray()            # the last written bytes, starting at written position _recent_at
        self._recent_at = 0
        self._segments: list[tuple[int, int]] = []  # (written position, station stream offset): a new segment
        self._open_pty()                            # starts after every drop (no host attached)

    # ------------------------------------------------------------------ lifecycle
    def _open_pty(self) -> None:
        master, slave = pty.openpty()
        tty.setraw(slave)                     # canonical mode would hold bytes until a newline
        self.slave_path = os.ttyname(slave)
        os.close(slave)                       # we are the device side: only the host keeps the slave open
        os.set_blocking(master, False)
        self._master = master
        self._unsent = b""
        self._written = self._recent_at = 0
        self._recent = bytearray()
        self._segments = [(0, self.link.bytes_taken)]
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

    def unplug(self) -> None:
        """Pull the cable: the host's port dies. Frames still queued in the emulator are lost; bytes already in
        the host's tty get up to `UNPLUG_DRAIN_S` to be read, and whatever the host has not read by then is
        lost as well (as on a real USB disconnect) and marked so in the ground truth, exactly (module doc)."""
        if self._master < 0:
            return
        self._stop_thread()
        chunks = self._collect_unread()
        os.close(self._master)
        self._master = -1
        self._remove_symlink()
        written_end = self.link.bytes_taken - len(self._unsent)  # stream offset past the last written byte
        missed = self._locate(chunks)         # written positions the host never got, in order
        self.bytes_lost_at_unplug += sum(map(len, chunks))
        self.last_unplug_holes = [r for start, end in missed for r in self._stream_ranges(start, end)]
        lost = self._undecodable(missed)      # ... widened to the frames the host's decoder cannot recover
        delivered = written_end
        if lost and lost[-1][1] == self._written:
            delivered = self._to_stream(lost.pop()[0])          # the host's stream simply ends there
        for start, end in lost:               # a read raced the collection: holes inside the host's stream
            for lo, hi in self._stream_ranges(start, end):
                self.link.discard(lo, hi)
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
        self._remove_symlink()

    def _remove_symlink(self) -> None:
        if self.symlink is not None and self.symlink.is_symlink():
            self.symlink.unlink()

    def __enter__(self) -> PtyTransport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ unplug accounting
    def _collect_unread(self) -> list[bytes]:
        """Wait (bounded) until the host has read every written byte, then read the rest ourselves. Returns the
        chunks read, in stream order; afterwards no written byte is left in the kernel."""
        hup = select.poll()                   # before our own descriptor makes the slave look open
        hup.register(self._master, select.POLLIN)
        host_attached = not any(mask & select.POLLHUP for _, mask in hup.poll(0))
        try:
            fd = os.open(self.slave_path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError:
            return []                         # cannot look (e.g. the host set TIOCEXCL): count it all delivered
        try:
            poller = select.poll()
            poller.register(fd, select.POLLIN)
            deadline = time.monotonic() + (UNPLUG_DRAIN_S if host_attached else 0.0)
            while not self._kernel_empty(fd, poller) and time.monotonic() < deadline:
                time.sleep(0.002)
            chunks = []
            while True:
                if chunk := self._read_slave(fd):
                    chunks.append(chunk)
                elif self._kernel_empty(fd, poller):
                    return chunks
        finally:
            os.close(fd)

    @staticmethod
    def _read_slave(fd: int) -> bytes:
        try:
            return os.read(fd, 1 << 16)
        except BlockingIOError:
            return b""

    @staticmethod
    def _kernel_empty(fd: int, poller: select.poll) -> bool:
        """No written byte is left for the slave to read: the read buffer is empty (FIONREAD) and poll(), which
        with an empty read buffer first waits for the flip-buffer worker, sees no input either."""
        if int.from_bytes(fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"), "little"):
            return False
        return not poller.poll(0)

    def _locate(self, chunks: list[bytes]) -> list[tuple[int, int]]:
        """Written-position ranges [start, end) the host never got, given the chunks we read in its place."""
        if not chunks:
            return []
        recent, base = bytes(self._recent), self._recent_at
        taken = b"".join(chunks)
        if recent.endswith(taken):            # the usual case: the host's stream ends where ours begins
            return [(self._written - len(taken), self._written)]
        spans: list[tuple[int, int]] = []     # the host read in between: place each chunk, last first
        pos = len(recent)
        for chunk in reversed(chunks):
            i = recent.rfind(chunk, 0, pos)
            if i < 0:
                raise RuntimeError("pty unplug: bytes read back from the slave were never written")
            if spans and spans[-1][0] == base + i + len(chunk):
                spans[-1] = (base + i, spans[-1][1])
            else:
                spans.append((base + i, base + i + len(chunk)))
            pos = i
        return spans[::-1]

    def _undecodable(self, missed: list[tuple[int, int]]) -> list[tuple[int, int]]:
        """`missed` widened for the host's decoder: unless the last byte the host got before a hole was a
        delimiter (or the hole starts the port's stream), the decoder still holds a partial frame, which merges
        with the bytes after the hole, up to the next delimiter, into one bad frame."""
        recent, base = self._recent, self._recent_at
        lost: list[tuple[int, int]] = []
        for start, end in missed:
            pending = start > 0 and (start <= base or recent[start - 1 - base] != 0)
            if end < self._written and pending:
                nxt = recent.find(b"\0", end - base)
                end = self._written if nxt < 0 else base + nxt + 1
            if lost and lost[-1][1] >= start:
                lost[-1] = (lost[-1][0], max(lost[-1][1], end))
            else:
                lost.append((start, end))
        return lost

    def _to_stream(self, position: int) -> int:
        at, offset = max(s for s in self._segments if s[0] <= position)
        return offset + position - at

    def _stream_ranges(self, start: int, end: int) -> list[tuple[int, int]]:
        """Written positions [start, end) as station stream ranges (split where output was dropped)."""
        bounds = [at for at, _ in self._segments if start < at < end] + [end]
        out, lo = [], start
        for hi in bounds:
            out.append((self._to_stream(lo), self._to_stream(lo) + hi - lo))
            lo = hi
        return out

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
                if n:
                    self._recent += self._unsent[:n]
                    self._written += n
                    if len(self._recent) > 2 * _RECENT_BYTES:
                        self._recent_at += len(self._recent) - _RECENT_BYTES
                        del self._recent[:-_RECENT_BYTES]
                        while len(self._segments) > 1 and self._segments[1][0] <= self._recent_at:
                            del self._segments[0]
                self._unsent = self._unsent[n:]
                self.bytes_written += n

    def _drop_unsent(self) -> None:
        if self._unsent:
            end = self.link.bytes_taken
            self.link.discard(end - len(self._unsent), end)
            self.bytes_dropped_no_host += len(self._unsent)
            self._unsent = b""
            # Bytes written earlier stay in the kernel for the next host to open the port; the next write
            # continues the stream after the gap.
            if self._segments[-1][0] == self._written:
                self._segments[-1] = (self._written, end)
            else:
                self._segments.append((self._written, end))
