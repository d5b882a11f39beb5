"""Device faults: impossible HELLO / batch fields, device ticks stepping back, links that cannot open,
oversized payloads, and command values that do not fit the wire."""
from __future__ import annotations

import os
import struct
import time

import numpy as np
import pytest
from cobs.cobs import encode as cobs_encode

import firmware_protocol as fp
from firmware_protocol.framing import CRC, HEADER, MAX_ENCODED_FRAME_BYTES, MAX_WIRE_FRAME_BYTES, crc32
from gateway.daemon import Gateway
from gateway.server import RequestError
from gateway.station import StationReader

from .test_station_reader import HELLO, Sink, batch, wait_for


def _hello(**changes) -> fp.Hello:
    fields = {"firmware_version": HELLO.firmware_version, "station_serial": HELLO.station_serial,
              "boot_id": HELLO.boot_id, "tick_rate_hz": HELLO.tick_rate_hz,
              "supported_rates_hz": HELLO.supported_rates_hz, "supported_ranges_g": HELLO.supported_ranges_g,
              "sensors": HELLO.sensors, **changes}
    return fp.Hello(**fields)


class _Frames:
    """Encodes messages of station 3 with consecutive sequence numbers."""

    def __init__(self):
        self.seq = 0

    def __call__(self, *messages) -> bytes:
        out = b""
        for m in messages:
            out += fp.encode(m, 3, self.seq)
            self.seq += 1
        return out


def _reader(sink: Sink) -> StationReader:
    return StationReader("replay", sink)  # fed directly: the same decode path as a live link, no thread


def _samples(sink: Sink) -> int:
    return sum(len(b.counter) for b in sink.blocks)


def test_hello_with_zero_tick_rate_is_refused_counted_and_the_link_kept(pty_pair):
    master, path = pty_pair
    sink = Sink()
    reader = StationReader(path, sink).start()
    try:
        frames = _Frames()
        assert wait_for(lambda: reader.status()["link"] == "connecting" and reader._link is not None)
        os.write(master, frames(_hello(tick_rate_hz=0), *[batch(0, i * 10, 1000 + i * 100_000, 10) for i in range(30)]))
        assert wait_for(lambda: reader.status()["invalid_fields"] == 1)
        status = reader.status()
        assert status["link"] == "connecting" and status["internal_errors"] == 0 and status["reconnects"] == 0
        assert "tick_rate_hz 0" in status["last_invalid"]
        assert [e for e in sink.events if e[1] == "warning" and "refused HELLO tick_rate_hz 0" in e[2]]
        # the same link then delivers a valid HELLO: the held-back batches go through, none lost
        os.write(master, frames(HELLO))
        assert wait_for(lambda: _samples(sink) == 300)
        assert reader.status()["link"] == "streaming" and reader.status()["internal_errors"] == 0
    finally:
        reader.stop()


@pytest.mark.parametrize("bad, why", [
    (fp.SampleBatch(0, 0, 0, 1000, 0, fp.scale_for_range(8), np.zeros((5, 3), np.int16)), "period_ticks_q8 is 0"),
    (fp.SampleBatch(0, 0, 0, 1000, 1, fp.scale_for_range(8), np.zeros((5, 3), np.int16)), "outside"),
    (fp.SampleBatch(0, 0, 0, 1000, 2_560_000, float("nan"), np.zeros((5, 3), np.int16)), "scale_g_per_lsb nan"),
    (fp.SampleBatch(0, 0, 0, 1000, 2_560_000, -0.001, np.zeros((5, 3), np.int16)), "not a positive number"),
])
def test_batches_with_impossible_fields_are_refused(bad, why):
    sink = Sink()
    reader = _reader(sink)
    frames = _Frames()
    reader.feed(frames(HELLO, batch(0, 0, 1000, 10), bad, batch(0, 10, 101_000, 10)), 10.0)
    assert _samples(sink) == 20 and reader.invalid_fields == 1 and reader.internal_errors == 0
    assert why in reader.last_invalid
    assert sum("refused SAMPLE_BATCH" in e[2] for e in sink.events) == 1


@pytest.mark.parametrize("hello, why", [
    (_hello(tick_rate_hz=10), "tick_rate_hz 10 outside"),
    (_hello(sensors=(fp.SensorInfo(0, 1, 0, 8),)), "rate_hz 0 outside"),
    (_hello(sensors=(fp.SensorInfo(0, 1, 100, 0),)), "range_g 0 is not positive"),
    (_hello(sensors=(fp.SensorInfo(1, 1, 100, 8), fp.SensorInfo(1, 1, 100, 8))), "duplicates"),
])
def test_impossible_hello_fields_are_refused(hello, why):
    sink = Sink()
    reader = _reader(sink)
    reader.feed(_Frames()(hello, batch(0, 0, 1000, 10)), 1.0)
    assert reader.hello is None and reader.invalid_fields == 1 and why in reader.last_invalid
    assert _samples(sink) == 0


def test_refusal_events_are_rate_limited_but_every_refusal_is_counted():
    sink = Sink()
    reader = _reader(sink)
    frames = _Frames()
    bad = fp.SampleBatch(0, 0, 0, 1000, 0, fp.scale_for_range(8), np.zeros((5, 3), np.int16))
    reader.feed(frames(HELLO, *[bad] * 60), 1.0)
    assert reader.invalid_fields == 60 and sum("refused" in e[2] for e in sink.events) == 1


def test_ticks_stepping_back_start_a_new_epoch_with_an_event():
    sink = Sink()
    reader = _reader(sink)
    frames = _Frames()
    t = 100.0
    reader.feed(frames(HELLO), t)
    for i in range(50):  # 5 s of one sensor, 10 samples per 0.1 s batch
        reader.feed(frames(batch(0, i * 10, 5_000_000 + i * 100_000, 10)), t + 0.1 * (i + 1))
    assert reader.unwrapper.epoch == 0
    # the device clock steps back by 0.99 s: well inside the unwrapper's 2 s tolerance
    back = 5_000_000 + 50 * 100_000 - 990_000
    reader.feed(frames(batch(0, 500, back, 10)), t + 5.1)
    assert reader.unwrapper.epoch == 1
    assert [e for e in sink.events if "device ticks went back by 0.9" in e[2] and "sensor 0" in e[2]]
    assert sink.blocks[-1].epoch == 1 and sink.blocks[-2].epoch == 0
    # clock beacons too
    reader.feed(frames(fp.ClockSync(back + 200_000, 1)), t + 5.3)
    reader.feed(frames(fp.ClockSync(back + 100_000, 2)), t + 5.4)
    assert reader.unwrapper.epoch == 2 and "clock beacons" in sink.events[-1][2]


def test_sensors_interleaving_out_of_order_is_not_a_step_back():
    sink = Sink()
    reader = _reader(sink)
    frames = _Frames()
    reader.feed(frames(HELLO), 1.0)
    for i in range(20):  # sensor 1's batch arrives before sensor 0's older one: normal radio reordering
        reader.feed(frames(batch(1, i * 10, 1_000_000 + i * 100_000 + 5_000, 10),
                           batch(0, i * 10, 1_000_000 + i * 100_000, 10)), 1.0 + 0.1 * i)
    assert reader.unwrapper.epoch == 0 and _samples(sink) == 400


def test_missing_port_and_bad_urls_say_why_in_status_and_once_in_the_events(tmp_path):
    missing = str(tmp_path / "ttyACM9")
    sources = [missing, "emu://x?sensors=abc", "nosuchscheme://x"]
    with Gateway(sources, listen=("127.0.0.1", 0), record_dir=tmp_path, reconnect_interval_s=0.02) as gw:
        assert wait_for(lambda: all(s["link_error"] for s in gw.list_stations()))
        time.sleep(0.3)  # ~15 more failed retries each
        stations = {s["source"]: s for s in gw.list_stations()}
    assert missing in stations[missing]["link_error"] and "cannot open" in stations[missing]["link_error"]
    assert "sensors" in stations["emu://x?sensors=abc"]["link_error"]
    assert "nosuchscheme" in stations["nosuchscheme://x"]["link_error"]


def test_link_error_event_once_per_reason(tmp_path):
    sink = Sink()
    reader = StationReader(str(tmp_path / "nope"), sink, reconnect_interval_s=0.01).start()
    try:
        assert wait_for(lambda: reader.status()["link_error"] is not None)
        time.sleep(0.2)
    finally:
        reader.stop()
    assert sum("cannot open link" in e[2] for e in sink.events) == 1


def _raw_frame(msg_type: int, payload: bytes) -> bytes:
    body = HEADER.pack(1, msg_type, 3, 0, len(payload) & 0xFFFF) + payload
    return cobs_encode(body + CRC.pack(crc32(body))) + b"\x00"


def test_payload_over_4096_bytes_is_refused_even_when_it_encodes_small():
    decoder = fp.StreamDecoder()
    big = _raw_frame(0x7F, bytes(4100))  # all zeros: COBS makes it ~4115 bytes, under the encoded limit
    assert len(big) - 1 <= MAX_ENCODED_FRAME_BYTES
    legal = _raw_frame(0x7F, bytes(range(1, 256)) * 16 + bytes(range(1, 17)))  # 4096 bytes, no zeros: worst case
    assert len(legal) == MAX_WIRE_FRAME_BYTES == 4128 and len(legal) - 1 == MAX_ENCODED_FRAME_BYTES == 4127
    decoder.feed(big + legal)
    assert decoder.stats.length_errors == 1 and decoder.stats.unknown_types == 1  # the legal one passed framing


def test_protocol_md_sizes_agree_with_the_code():
    text = (fp.__path__[0] + "/PROTOCOL.md")
    doc = open(text, encoding="utf-8").read()
    assert "4110 B body" in doc and f"{MAX_ENCODED_FRAME_BYTES} B COBS" in doc
    assert f"{MAX_WIRE_FRAME_BYTES} B on the wire" in doc
    assert f"more than {MAX_ENCODED_FRAME_BYTES} bytes without a delimiter" in doc
    assert "4114" not in doc and "4133" not in doc


@pytest.mark.parametrize("args, why", [
    ({"rate_hz": 2 ** 40}, "'rate_hz' = 1099511627776 is outside -2147483648..2147483647"),
    ({"rate_hz": "fast"}, "'rate_hz' must be an integer, got 'fast'"),
    ({"rate_hz": 100.5}, "'rate_hz' must be an integer"),
    ({"rate_hz": 100, "sensor": 300}, "'sensor' = 300 is outside 0..255"),
    ({"rate_hz": [1]}, "'rate_hz' must be an integer"),
])
def test_command_values_that_do_not_fit_the_wire_get_a_clear_error(tmp_path, args, why):
    gw = Gateway(["/nonexistent/port"], listen=("127.0.0.1", 0), record_dir=tmp_path)
    try:
        with pytest.raises(RequestError) as info:
            gw.handle_request("station_command", {"station": "/nonexistent/port", "command": "set_rate", "args": args})
        assert str(info.value) == f"set_rate: {why}" or why in str(info.value)
        assert "struct" not in str(info.value)
    finally:
        gw.server.close()


FORGED = "buffer overflow\n2026-12-02 12:00:00 CRITICAL gateway: operator secret rotated\r\x1b[2J\u202egnp.exe\u200b"


def test_station_error_text_is_escaped_and_its_events_throttled(caplog):
    """Issue 22: a station's ERROR text went into events and logs unchanged (a newline forged a log line, U+202E
    reversed the text) and 500 ERROR frames made 500 events. Through a real Gateway's event path (which logs)."""
    from gateway.device_text import escape

    gw = Gateway([], listen=("127.0.0.8", 0), record_dir="/nonexistent-never-written")
    sink = Sink()
    reader = StationReader("replay", sink)
    reader.sink = _Tee(sink, gw)
    frames = _Frames()
    try:
        with caplog.at_level("INFO", logger="gateway"):
            reader.feed(frames(HELLO, *[fp.Error(1, FORGED)] * 500), 1.0)
    finally:
        gw.server.close()
    errors = [e for e in sink.events if "station error" in e[2]]
    assert len(errors) == 3  # the burst; the rest counted
    status = reader.status()
    assert status["device_errors"] == 500 and status["device_error_events_suppressed"] == 497
    for text in [e[2] for e in errors] + [status["last_device_error"]] + [r.getMessage() for r in caplog.records]:
        assert text.isprintable() and "\u202e" not in text and "\x1b" not in text, repr(text)
    assert "\\n2026-12-02 12:00:00 CRITICAL" in errors[0][2] and "\\u202e" in errors[0][2] and "\\x1b[2J" in errors[0][2]
    assert escape("a\\nb") == "a\\\\nb"  # a backslash in the text cannot forge an escape
    assert escape("x" * 500).endswith("... (300 more characters)") and len(escape("x" * 500)) < 230


class _Tee:
    """Station events to the test's sink and to a real gateway's publish/log path."""

    def __init__(self, sink, gateway):
        self.sink, self.gateway = sink, gateway

    def on_samples(self, block):
        self.sink.on_samples(block)

    def on_station_event(self, station, level, message, details=None):
        self.sink.on_station_event(station, level, message, details)
        self.gateway.on_station_event(station, level, message, details)


def test_event_throttle_lets_a_burst_through_then_one_per_interval_and_counts_the_rest():
    from gateway.device_text import EventThrottle

    throttle = EventThrottle(burst=3, interval_s=10.0)
    assert [throttle.allow(0.0) for _ in range(5)] == [True, True, True, False, False]
    assert not throttle.allow(9.0) and throttle.suppressed == 3
    assert throttle.allow(11.0) and throttle.take_suppressed() == 3 and throttle.suppressed_total == 3
    assert not throttle.allow(11.5)


def test_host_time_never_steps_back_across_an_epoch_restart_or_a_warm_up_refit():
    """Issue 22, item 10: the host time of a sample comes from the clock estimate, which restarts at a new epoch
    and re-fits while warming up; either stepped a stream's recorded time back (2-16 ms, up to 9 ms in
    warm-up). Each stream's t_host_s must increase; the raw ticks, arrivals and epoch stay as they were."""
    sink = Sink()
    reader = _reader(sink)
    frames = _Frames()
    t = 100.0
    reader.feed(frames(HELLO), t)
    # warm-up: single-sample batches 10 ms apart arriving 30 ms late, then one with no delivery latency: the
    # lower-envelope fit moves 30 ms earlier at once, which put that sample 20 ms before its predecessor
    for i in range(20):
        reader.feed(frames(batch(0, i, 1_000_000 + i * 10_000, 1)), t + 0.01 * i + 0.030)
    reader.feed(frames(batch(0, 20, 1_000_000 + 20 * 10_000, 1)), t + 0.20)
    # a new epoch: the device clock steps back; its first batch (10 samples, 90 ms) arrives 50 ms after the last
    last_arrival = t + 0.20
    reader.feed(frames(batch(0, 21, 1_000_000 + 21 * 10_000 - 900_000, 10)), last_arrival + 0.05)
    assert reader.unwrapper.epoch == 1
    t_host = np.concatenate([b.t_host_s for b in sink.blocks])
    assert np.all(np.diff(t_host) > 0), np.diff(t_host)
    held = reader.status()["sensors"][0]["host_time_held"]
    assert held >= 2  # the warm-up step and the new epoch's earliest samples
    # what was held is not rewritten: the evidence for the offline re-fit is intact
    assert np.array_equal(np.concatenate([b.arrival_s for b in sink.blocks])[-10:], np.full(10, last_arrival + 0.05))
    assert [b.epoch for b in sink.blocks][-2:] == [0, 1]


def test_a_motion_batch_with_an_impossible_gyro_scale_is_refused():
    """A MOTION_BATCH whose angular-rate scale is NaN (a sender bug the decoder cannot see: the layout is fine)
    is refused and counted like any impossible field; the accelerations-only batches around it go through."""
    from firmware_protocol.framing import frame_payload

    good = fp.SampleBatch(0, 0, 10, 101_000, 2_560_000, fp.scale_for_range(8), np.zeros((5, 3), np.int16), None,
                          np.zeros((5, 3), np.int16), 0.001)
    payload = bytearray(fp.codec.pack_motion_batch(good))
    payload[22:26] = struct.pack("<f", float("nan"))  # the gyro scale (PROTOCOL.md 2.8, offset 22)
    sink = Sink()
    reader = _reader(sink)
    frames = _Frames()
    data = frames(HELLO, batch(0, 0, 1000, 10)) + frame_payload(fp.MessageType.MOTION_BATCH, bytes(payload), 3, 2)
    frames.seq = 3
    reader.feed(data + frames(batch(0, 15, 151_000, 10)), 10.0)
    assert _samples(sink) == 20 and reader.invalid_fields == 1 and "gyro_scale_rps_per_lsb nan" in reader.last_invalid
