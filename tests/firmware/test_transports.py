"""emu:// pyserial URL handler and the HID report transport (fake hidapi device) over emulated stations."""
from __future__ import annotations

import time

import pytest
import serial

# importing the package also registers the emu:// pyserial URL scheme
from firmware_protocol import Ack, ClockSync, Command, Hello, Opcode, SampleBatch, StreamDecoder, encode
from firmware_protocol.emulator import BaseStation, StationConfig
from firmware_protocol.emulator.hid_transport import FakeHidBus
from firmware_protocol.hid import (
    IN_REPORT_ID, OUT_REPORT_ID, HidapiTransport, pack_reports, unpack_report,
)
from firmware_protocol.emulator.link import EmulatorLink
from firmware_protocol.emulator.protocol_emu import STATIONS

from .host import Host, assert_matches_ground_truth


@pytest.fixture(autouse=True)
def _forget_url_stations():
    yield
    STATIONS.clear()


def test_emu_url_manual_clock_streams_exactly():
    port = serial.serial_for_url("emu://urltest?sensors=4&rate=200&loss=0.05&batch=8&seed=3&clock=manual",
                                 timeout=0.01)
    host = Host(port.link, read=lambda: port.read(port.in_waiting or 1), write=port.write)
    host.run(0.1)
    hello = host.messages(Hello)[0]
    assert len(hello.sensors) == 4 and {s.rate_hz for s in hello.sensors} == {200}
    assert host.transact(Opcode.START_STREAMING) == Ack(1, Opcode.START_STREAMING)
    host.run(5.0)
    host.transact(Opcode.STOP_STREAMING)
    host.run(0.2)
    fates = assert_matches_ground_truth(host.frames, port.link.station)
    assert fates[1] > 4 * 200 * 4.5 and fates[2] > 0                   # delivered, and some radio drops
    assert {b.n_samples for b in host.messages(SampleBatch)[:-4]} == {8}
    port.close()


def test_emu_url_wall_clock_advances_by_itself():
    """Nobody advances the station: reading alone shows 2 s of device time pass (0.1 s of wall time at 20x), and
    never faster than 20x the wall time the reads took. Polls with a generous deadline instead of reading for a fixed
    0.3 s, which a starved machine could spend without a single read."""
    started = time.monotonic()  # before the station exists: it cannot have run longer than this
    port = serial.serial_for_url("emu://walltest?sensors=2&autostart=1&speed=20", timeout=0.05)
    decoder = StreamDecoder()
    ticks: list[int] = []
    while (not ticks or max(ticks) - min(ticks) < 2_000_000) and time.monotonic() - started < 60.0:
        ticks += [f.message.first_sample_ticks for f in decoder.feed(port.read(port.in_waiting or 1))
                  if isinstance(f.message, SampleBatch)]
    elapsed_s = time.monotonic() - started
    span_ticks = max(ticks) - min(ticks)
    assert 2.0 <= span_ticks / 1e6 <= 20 * elapsed_s  # 1 MHz ticks
    assert decoder.stats.corrupt_frames == 0
    port.close()


def test_emu_url_unplug_reopen_and_bad_options():
    port = serial.serial_for_url("emu://plug?clock=manual&sensors=1", timeout=0)
    link = port.link
    link.advance(0.5)
    assert StreamDecoder().feed(port.read(10_000))[0].message.__class__ is Hello
    link.unplug()
    with pytest.raises(serial.SerialException, match="disconnected"):
        port.read(1)
    port.close()
    with pytest.raises(serial.SerialException, match="unplugged"):
        serial.serial_for_url("emu://plug", timeout=0)
    link.replug()
    again = serial.serial_for_url("emu://plug", timeout=0)          # same station, reattached by name
    assert again.link is link
    link.advance(0.1)
    first = StreamDecoder().feed(again.read(10_000))[0]
    assert first.seq == 0 and isinstance(first.message, Hello)
    with pytest.raises(serial.SerialException, match="unknown station option 'bogus'"):
        serial.serial_for_url("emu://bad?bogus=1")
    with pytest.raises(serial.SerialException, match="loss=2"):
        serial.serial_for_url("emu://bad2?loss=2")


def test_hid_reports_round_trip():
    data = bytes(range(256)) * 3
    reports = pack_reports(data, IN_REPORT_ID)
    assert all(len(r) == 64 and r[0] == IN_REPORT_ID for r in reports)
    assert b"".join(unpack_report(r, IN_REPORT_ID) for r in reports) == data
    with pytest.raises(ValueError):
        unpack_report(reports[0], OUT_REPORT_ID)
    with pytest.raises(ValueError):
        unpack_report(bytes([IN_REPORT_ID, 63]) + bytes(62), IN_REPORT_ID)


def _reference_bytes(config: StationConfig, script: list[tuple[float, Command]], end_s: float) -> bytes:
    """The same station driven directly: each command written at the same emulated time."""
    station = BaseStation(config)
    out = b""
    for t, command in script:
        out += station.advance(t - station.now_s)
        station.write(encode(command, config.station_id, 0))
    return out + station.advance(end_s - station.now_s)


def test_fake_hid_device_carries_the_same_frames():
    config = StationConfig(n_sensors=3, rate_hz=200, radio_loss=0.03, byte_corruption=0.0005, seed=9)
    link = EmulatorLink(BaseStation(config))
    bus = FakeHidBus()
    path = bus.attach(link)
    assert [d["path"] for d in bus.enumerate(0x1209, 0xC0DE)] == [path]
    transport = HidapiTransport.open(path=path, device_factory=bus.device)
    stream = bytearray()
    script = [(0.5, Command(1, Opcode.START_STREAMING)), (3.5, Command(2, Opcode.STOP_STREAMING))]

    def read_all():
        while chunk := transport.read(timeout_ms=1):
            stream.extend(chunk)

    for t, command in script:
        link.advance(t - link.station.now_s)
        read_all()
        transport.write(encode(command, config.station_id, 0))
    for _ in range(10):
        link.advance(0.1)
        read_all()
    assert bytes(stream) == _reference_bytes(config, script, 4.5)
    decoder = StreamDecoder()
    frames = decoder.feed(bytes(stream))
    assert isinstance(frames[0].message, Hello) and isinstance(frames[1].message, Ack)
    fates = assert_matches_ground_truth(frames, link.station)
    assert fates[1] > 3 * 200 * 2.5

    device = bus.device()
    device.open(0x1209, 0xC0DE)
    assert device.write(bytes([0x07]) + bytes(63)) == -1                 # wrong report id, like hidapi's -1
    assert device.get_product_string().startswith("Courtside")
    link.unplug()
    assert bus.enumerate() == []
    with pytest.raises(OSError):
        transport.read(timeout_ms=1)
    with pytest.raises(OSError):
        bus.device().open(0x1209, 0xC0DE)


def test_hid_transport_counts_foreign_reports():
    class Device:
        reports = [bytes([0x03, 2, 1, 2]) + bytes(60), pack_reports(b"\x00abc", IN_REPORT_ID)[0], []]

        def read(self, n, timeout):
            return list(self.reports.pop(0))

    transport = HidapiTransport(Device())
    assert transport.read(1) == b"" and transport.bad_reports == 1
    assert transport.read(1) == b"\x00abc"
    assert transport.read(1) == b""


def test_emu_url_bytes_taken_before_unplug_stay_readable():
    port = serial.serial_for_url("emu://buffered?clock=manual&sensors=2&autostart=1&seed=4", timeout=0)
    port.link.advance(1.0)
    assert port.in_waiting > 0                      # now in the port's receive buffer
    port.link.advance(0.5)                          # more output, still inside the station link
    port.link.unplug()
    frames = StreamDecoder().feed(port.read(1_000_000))
    with pytest.raises(serial.SerialException):
        port.read(1)
    fates = assert_matches_ground_truth(frames, port.link.station)
    assert fates[1] > 0 and fates[4] > 0            # delivered before the cut, lost after it


def test_realtime_round_trip_clock_sync_is_stamped_between_send_and_reply():
    """In wall-clock mode a REQUEST_CLOCK_SYNC is answered with the station time of its arrival: mapped back
    to the host clock it lies between the send and the receipt (what a round-trip estimator relies on)."""
    port = serial.serial_for_url("emu://rtt?sensors=1&drift=0", timeout=0.01)
    decoder = StreamDecoder()
    for command_id in range(1, 6):
        sent = time.monotonic()
        port.write(encode(Command(command_id, Opcode.REQUEST_CLOCK_SYNC), 1, command_id))
        reply = None
        while reply is None:
            for f in decoder.feed(port.read(port.in_waiting or 1)):
                if isinstance(f.message, ClockSync) and f.message.echo_command_id == command_id:
                    reply = f.message
        received = time.monotonic()
        t_true = port.link.station.boot_time_s + reply.station_ticks / 1e6
        assert sent - 1e-6 <= port.link.true_to_monotonic(t_true) <= received + 1e-6
    port.close()
