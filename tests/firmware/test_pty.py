"""The emulated station over a real pseudo-terminal, opened with pyserial like /dev/ttyACM0."""
from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest
import serial

from firmware_protocol import Ack, ClockSync, Hello, Nack, NackReason, Opcode, SampleBatch, Status, StreamDecoder
from firmware_protocol.emulator import BaseStation, Fate, StationConfig, TraceSource
from firmware_protocol.emulator.link import EmulatorLink
from firmware_protocol.emulator.pty_transport import PtyTransport

from .host import Host, assert_matches_ground_truth


def _trace(n_sensors: int = 6, fps: float = 200.0, seconds: float = 7.0) -> TraceSource:
    """Distinct smooth per-sensor signals up to +-6 g so every sample value is informative."""
    t = np.arange(int(fps * seconds)) / fps
    s = np.arange(n_sensors)[None, :, None]
    axis = np.arange(3)[None, None, :]
    acc = 6.0 * np.sin(2 * np.pi * (0.5 + 0.3 * s + 0.1 * axis) * t[:, None, None] + s + axis)
    return TraceSource(acc, fps)


@pytest.fixture
def pty_host():
    def make(config: StationConfig, motion=None):
        link = EmulatorLink(BaseStation(config, motion))
        transport = PtyTransport(link)
        port = serial.Serial(transport.slave_path, timeout=0.02)
        opened.append((transport, port))
        return transport, Host(link, read=lambda: port.read(port.in_waiting or 1), write=port.write)
    opened: list = []
    yield make
    for transport, port in opened:
        port.close()
        transport.close()


def test_acceptance_60s_six_sensors_loss_and_corruption_over_pty(pty_host):
    """Issue 2 acceptance: configure over the pty (ACK/NACK checked), stream 60 s from 6 sensors with 2 % radio
    loss and 0.1 % byte corruption; every undamaged sample is decoded bit-exactly and every loss is accounted."""
    config = StationConfig(n_sensors=6, rate_hz=100, range_g=12, radio_loss=0.02, byte_corruption=0.001,
                           drift_ppm=35.0, burst_probability=0.01, seed=2024)
    _, host = pty_host(config, _trace())
    host.run(0.2)
    assert host.transact(Opcode.SET_RATE, 333) == Nack(1, Opcode.SET_RATE, NackReason.UNSUPPORTED_VALUE)
    assert host.transact(Opcode.SET_RANGE, 8, target=9) == Nack(2, Opcode.SET_RANGE, NackReason.UNKNOWN_SENSOR)
    assert host.transact(Opcode.SET_RANGE, 8) == Ack(3, Opcode.SET_RANGE)
    assert host.transact(Opcode.SET_RATE, 100) == Ack(4, Opcode.SET_RATE)
    assert host.transact(Opcode.REQUEST_HELLO) == Ack(5, Opcode.REQUEST_HELLO)
    host.run(0.1)
    assert host.transact(Opcode.START_STREAMING) == Ack(6, Opcode.START_STREAMING)
    assert host.transact(Opcode.SET_RATE, 200) == Nack(7, Opcode.SET_RATE, NackReason.INVALID_STATE)
    host.run(60.0)
    assert host.transact(Opcode.STOP_STREAMING) == Ack(8, Opcode.STOP_STREAMING)
    host.run(0.5)                                  # bursty radio: let every batch in flight arrive

    hellos = host.messages(Hello)
    assert hellos and all(s.range_g == 8 and s.rate_hz == 100 for s in hellos[-1].sensors)
    fates = assert_matches_ground_truth(host.frames, host.station)
    truth = host.station.truth.samples()
    assert len(truth.fate) == sum(fates.values()) >= 6 * 100 * 60
    assert fates[Fate.IN_FLIGHT] == fates[Fate.LOST_UNPLUGGED] == 0
    assert fates[Fate.RADIO_DROPPED] > 0 and fates[Fate.WIRE_CORRUPTED] > 0
    assert fates[Fate.DELIVERED] + fates[Fate.RADIO_DROPPED] + fates[Fate.WIRE_CORRUPTED] == len(truth.fate)
    batches = host.messages(SampleBatch)
    assert all(b.scale_g_per_lsb == np.float32(8 / 32767) for b in batches)
    np.testing.assert_allclose(
        np.concatenate([b.acc_g() for b in batches]).std(), truth.acc_true_g.std(), rtol=0.05)

    # Frame accounting: gaps seen by the decoder == frames damaged between the first and last intact frame.
    frames = host.station.truth.frames()
    intact = np.flatnonzero(frames.intact)
    assert host.decoder.stats.seq_gaps == int(np.sum(~frames.intact[intact[0]:intact[-1]]))
    assert host.decoder.stats.corrupt_frames >= 1
    assert host.decoder.stats.frames_ok == len(intact)

    # Per sensor, every hole in the decoded counters is a sample the ground truth says was lost.
    for sid in range(6):
        counters = np.sort(np.concatenate([b.first_sample_counter + np.arange(b.n_samples)
                                           for b in batches if b.sensor_id == sid]))
        holes = int(np.sum(np.diff(counters) - 1))
        mine = truth.sensor_id == sid
        lost = ~truth.delivered[mine] & (truth.counter[mine] > counters[0]) & (truth.counter[mine] < counters[-1])
        assert holes == int(np.sum(lost))

    # The station's own radio-drop counter (last STATUS) matches the drops the ground truth recorded by then.
    last_status_frame = max(i for i, f in enumerate(frames.msg_type) if f == 0x04 and frames.intact[i])
    t_status = frames.t_sent_s[last_status_frame]
    dropped_batches = sum(1 for b in host.station.truth.batches
                          if b.fate == Fate.RADIO_DROPPED and b.t_true_s[-1] <= t_status)
    assert host.messages(Status)[-1].radio_drops == dropped_batches


def test_command_round_trips_over_pty(pty_host):
    _, host = pty_host(StationConfig(n_sensors=3, seed=1))
    host.run(0.05)
    assert host.transact(Opcode.IDENTIFY, 500, target=2) == Ack(1, Opcode.IDENTIFY)
    assert host.transact(Opcode.REQUEST_STATUS) == Ack(2, Opcode.REQUEST_STATUS)
    assert host.messages(Status)[-1].flags & 0x04                        # identifying
    assert host.transact(Opcode.IDENTIFY, -1) == Nack(3, Opcode.IDENTIFY, NackReason.UNSUPPORTED_VALUE)
    assert host.transact(99) == Nack(4, 99, NackReason.UNKNOWN_OPCODE)
    assert host.transact(Opcode.ENTER_CALIBRATION) == Ack(5, Opcode.ENTER_CALIBRATION)
    assert host.transact(Opcode.START_STREAMING) == Ack(6, Opcode.START_STREAMING)
    host.run(0.2)
    assert host.transact(Opcode.LEAVE_CALIBRATION) == Ack(7, Opcode.LEAVE_CALIBRATION)
    assert host.transact(Opcode.REQUEST_CLOCK_SYNC) == Ack(8, Opcode.REQUEST_CLOCK_SYNC)
    host.run(0.1)
    assert any(m.echo_command_id == 8 for m in host.messages(ClockSync))
    flags = [b.flags for b in host.messages(SampleBatch)]
    assert flags[0] == 1 and flags[-1] == 0                              # calibration flag follows the mode
    host.send(b"\x01\x02\x03\x00")                                      # garbage: ERROR BAD_FRAME, CRC counter
    assert host.transact(Opcode.REQUEST_STATUS) == Ack(9, Opcode.REQUEST_STATUS)
    assert host.messages(Status)[-1].crc_errors == 1
    assert host.decoder.stats.corrupt_frames == 0


def test_unplug_replug_over_pty(pty_host, tmp_path):
    """Pulling the cable kills the host's port and its stable path; the replugged station reboots (new boot id,
    seq 0 HELLO) behind that path again."""
    link = EmulatorLink(BaseStation(StationConfig(n_sensors=2, autostart=True, seed=5)))
    with PtyTransport(link, symlink=tmp_path / "station0") as transport:
        port = serial.Serial(str(tmp_path / "station0"), timeout=0.02)
        host = Host(link, read=lambda: port.read(port.in_waiting or 1), write=port.write)
        host.run(1.0)
        first_boot = host.messages(Hello)[0].boot_id
        old_path = transport.slave_path
        transport.unplug()
        with pytest.raises(serial.SerialException):
            for _ in range(10):
                port.read(1)
        port.close()
        assert not (tmp_path / "station0").exists()  # gone like udev's by-id path: no retry opens a reused pty
        link.advance(2.0)                                                # unplugged: time passes, nothing sent
        transport.replug()
        assert (tmp_path / "station0").resolve() == Path(transport.slave_path).resolve()
        port = serial.Serial(str(tmp_path / "station0"), timeout=0.02)
        host2 = Host(link, read=lambda: port.read(port.in_waiting or 1), write=port.write,
                     delivered=lambda: link.station.bytes_out - transport.bytes_dropped_no_host - host.bytes_read)
        host2.run(0.5)
        assert host2.transact(Opcode.START_STREAMING) == Ack(1, Opcode.START_STREAMING)
        host2.run(1.0)
        hello = host2.messages(Hello)[0]
        assert hello.boot_id != first_boot and host2.frames[0].seq == 0
        assert old_path  # the path may be reused by the kernel; the symlink is the stable name
        assert_matches_ground_truth(host.frames, link.station, boot=0)
        assert_matches_ground_truth(host2.frames, link.station, boot=1)
        port.close()


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_unplug_mid_stream_keeps_ground_truth_exact_for_a_live_reader(seed):
    """Real-time station, host reading in its own thread as a gateway does, cable pulled at an arbitrary moment:
    the host decodes exactly the samples the ground truth calls delivered (the rest are LOST_UNPLUGGED)."""
    link = EmulatorLink(BaseStation(StationConfig(n_sensors=6, autostart=True, burst_probability=0.02, seed=seed)),
                        realtime=True, speed=2.0)
    transport = PtyTransport(link)
    port = serial.Serial(transport.slave_path, timeout=0.05)
    decoder, frames = StreamDecoder(), []

    def read_until_unplugged():
        while True:
            try:
                frames.extend(decoder.feed(port.read(port.in_waiting or 1)))
            except serial.SerialException:
                return

    reader = threading.Thread(target=read_until_unplugged)
    reader.start()
    time.sleep(0.25 + 0.05 * seed)
    transport.unplug()
    reader.join(timeout=5)
    transport.close()
    port.close()
    fates = assert_matches_ground_truth(frames, link.station)
    assert fates[Fate.DELIVERED] > 0 and fates[Fate.LOST_UNPLUGGED] > 0
