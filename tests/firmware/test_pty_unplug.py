"""Pulling the cable of the pty transport while the host is not reading: the ground truth must say exactly which
bytes the host got (everything it can still read) and which died in the kernel's tty buffers with the port."""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest
import serial

from firmware_protocol.emulator import BaseStation, Fate, StationConfig
from firmware_protocol.emulator.link import EmulatorLink
from firmware_protocol.emulator.pty_transport import UNPLUG_DRAIN_S, PtyTransport

from .host import Host, assert_matches_ground_truth

N_TTY_READ_BUFFER = 4095  # what FIONREAD can see at most; a bigger backlog also sits in the flip buffer


def _open(transport_cls=PtyTransport, seed: int = 1):
    # 6 sensors x 1 kHz: ~70 kB of frames per emulated second, so a short advance fills the kernel's buffers
    link = EmulatorLink(BaseStation(StationConfig(n_sensors=6, rate_hz=1000, autostart=True, seed=seed)))
    transport = transport_cls(link)
    port = serial.Serial(transport.slave_path, timeout=0.02)
    host = Host(link, read=lambda: port.read(port.in_waiting or 1), write=port.write)
    return link, transport, port, host


def _wait_until_written(link: EmulatorLink, transport: PtyTransport) -> None:
    """Until the I/O thread has put everything into the pty, or the pty is full (it stops taking then)."""
    last, stable_since = -1, time.monotonic()
    while time.monotonic() - stable_since < 0.2:
        if transport.bytes_written != last:
            last, stable_since = transport.bytes_written, time.monotonic()
        if link.pending() == 0 and not transport._unsent:
            return
        time.sleep(0.005)


def _read_after_unplug(port: serial.Serial, host: Host) -> int:
    """Whatever the host can still read once the cable is out (nothing: the port is dead)."""
    got = 0
    deadline = time.monotonic() + 1.0
    while time.monotonic() < deadline:
        try:
            chunk = port.read(4096)
        except serial.SerialException:
            break
        got += len(chunk)
        host.frames += host.decoder.feed(chunk)
    host.bytes_read += got
    return got


def _assert_exact(host: Host, link: EmulatorLink, transport: PtyTransport) -> dict:
    """Samples, frames and bytes the host decoded are exactly those the ground truth calls delivered."""
    fates = assert_matches_ground_truth(host.frames, link.station)
    frames = link.station.truth.frames()
    np.testing.assert_array_equal(np.array([f.seq for f in host.frames]), frames.seq[frames.intact])
    assert host.bytes_read == transport.bytes_written - transport.bytes_lost_at_unplug
    lost = sum(end - start for start, end in transport.last_unplug_holes)
    assert lost == transport.bytes_lost_at_unplug
    return fates


@pytest.mark.parametrize("backlog_s", [0.01, 0.1, 0.4])  # in the read buffer / + flip buffer / pty full
def test_unplug_while_host_not_reading_counts_exactly_what_it_read(backlog_s):
    link, transport, port, host = _open()
    try:
        host.run(0.3)                            # a live host first: everything so far is read
        read_live = host.bytes_read
        link.advance(backlog_s)                  # then the host stops reading
        _wait_until_written(link, transport)
        backlog = transport.bytes_written - read_live
        t0 = time.monotonic()
        transport.unplug()
        unplug_s = time.monotonic() - t0
        assert _read_after_unplug(port, host) == 0
    finally:
        port.close()
        transport.close()
    # the host got its chance to read, then the cut; the upper bound only catches a hang (a starved machine took
    # 1.46 s here, so + 0.5 s was a timing assert)
    assert UNPLUG_DRAIN_S <= unplug_s < UNPLUG_DRAIN_S + 10.0
    assert transport.bytes_lost_at_unplug == backlog > 0   # every written byte it did not read died in the kernel
    if backlog_s >= 0.1:
        assert backlog > N_TTY_READ_BUFFER       # ... including the part FIONREAD cannot see
    fates = _assert_exact(host, link, transport)
    assert fates[Fate.DELIVERED] > 0 and fates[Fate.LOST_UNPLUGGED] > 0


@pytest.mark.parametrize("read_first", [0, 1001])       # hole at a frame boundary / inside a frame
def test_host_reading_while_the_transport_collects_leaves_exact_holes(read_first):
    """The host resumes reading just as the transport takes the unread bytes: the bytes the transport took
    are holes inside the host's stream, and the frames the host's decoder merged across them are lost too."""
    grabbed: list[int] = []

    class Racing(PtyTransport):
        def _read_slave(self, fd: int) -> bytes:
            chunk = super()._read_slave(fd)
            if chunk and not grabbed:            # after our first read, let the host read a piece
                data = port.read(1500)
                grabbed.append(len(data))
                host.bytes_read += len(data)
                host.frames += host.decoder.feed(data)
            return chunk

    link, transport, port, host = _open(Racing, seed=7)
    try:
        host.run(0.3)
        link.advance(0.15)
        _wait_until_written(link, transport)
        if read_first:
            data = port.read(read_first)
            host.bytes_read += len(data)
            host.frames += host.decoder.feed(data)
        transport.unplug()
        _read_after_unplug(port, host)
    finally:
        port.close()
        transport.close()
    assert grabbed == [1500]
    assert len(transport.last_unplug_holes) == 2         # one inside the host's stream, then its tail
    fates = _assert_exact(host, link, transport)
    assert fates[Fate.DELIVERED] > 0 and fates[Fate.LOST_UNPLUGGED] > 0


def test_unplug_with_no_host_attached_loses_what_the_last_host_left_unread():
    """A host that closed its port with bytes unread leaves them in the kernel (the next opener would get them);
    an unplug then destroys them, without waiting for a reader that is not there."""
    link, transport, port, host = _open(seed=3)
    try:
        host.run(0.2)
        link.advance(0.05)
        _wait_until_written(link, transport)
        port.close()
        unread = transport.bytes_written - host.bytes_read
        link.advance(0.05)                       # dropped: nobody has the port open
        time.sleep(0.05)
        t0 = time.monotonic()
        transport.unplug()
        assert time.monotonic() - t0 < UNPLUG_DRAIN_S
    finally:
        transport.close()
    assert transport.bytes_lost_at_unplug == unread > 0
    fates = _assert_exact(host, link, transport)
    assert fates[Fate.DELIVERED] > 0 and fates[Fate.LOST_UNPLUGGED] > 0


def test_live_reader_gets_everything_written_before_the_cut():
    """A host reading promptly in its own thread loses nothing that reached the pty (unplug() waits for it)."""
    link, transport, port, host = _open(seed=5)

    def read_until_unplugged():
        while True:
            try:
                data = port.read(port.in_waiting or 1)
            except serial.SerialException:
                return
            host.bytes_read += len(data)
            host.frames += host.decoder.feed(data)

    try:
        host.run(0.2)
        reader = threading.Thread(target=read_until_unplugged)
        reader.start()
        link.advance(0.05)                       # ~3.5 kB on its way through the pty as the cable is pulled
        transport.unplug()
        reader.join(5)
    finally:
        port.close()
        transport.close()
    assert transport.bytes_lost_at_unplug == 0 and transport.last_unplug_holes == []
    fates = _assert_exact(host, link, transport)
    assert fates[Fate.DELIVERED] > 0
