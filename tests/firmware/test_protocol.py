"""Framing, codec and StreamDecoder: round trips, chunking, and exact accounting of injected damage."""
from __future__ import annotations

import binascii
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from firmware_protocol import (
    ClockSync, Command, Hello, MessageType, SampleBatch, StreamDecoder, encode, scale_for_range,
)
from firmware_protocol.framing import MAX_ENCODED_FRAME_BYTES, crc32, frame_payload
from firmware_protocol.codec import pack_sample_batch

from .strategies import messages, sample_batches, u16, u32


# The machine is shared: never fail on wall-clock deadlines or slow data generation.
RELAXED = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _stream(msgs: list, station_id: int = 7, first_seq: int = 1) -> tuple[bytes, list[tuple[int, int]]]:
    """Concatenated frames and each frame's [start, end) byte span (end includes its delimiter)."""
    frames = [encode(m, station_id, first_seq + i) for i, m in enumerate(msgs)]
    spans, pos = [], 0
    for f in frames:
        spans.append((pos, pos + len(f)))
        pos += len(f)
    return b"".join(frames), spans


def test_crc_parameters_are_the_documented_ones():
    assert crc32(b"123456789") == 0xCBF43926
    assert binascii.crc32(b"123456789") == zlib.crc32(b"123456789")


def test_known_frame_bytes():
    """A fixed message encodes to fixed bytes (guards the layout against accidental change)."""
    frame = encode(ClockSync(station_ticks=0x01020304, beacon_counter=5, echo_command_id=0), station_id=2, seq=1)
    body = bytes([1, 3, 2, 0, 1, 0, 0, 0, 10, 0, 4, 3, 2, 1, 5, 0, 0, 0, 0, 0])
    body += zlib.crc32(body).to_bytes(4, "little")
    assert StreamDecoder().feed(frame)[0].message == ClockSync(0x01020304, 5, 0)
    assert 0 not in frame[:-1] and frame[-1] == 0
    from cobs.cobs import decode
    assert decode(frame[:-1]) == body


@given(msg=messages, station_id=u16, seq=u32)
@settings(max_examples=400, **RELAXED)
def test_round_trip_every_message_type(msg, station_id, seq):
    decoder = StreamDecoder()
    frames = decoder.feed(encode(msg, station_id, seq))
    assert len(frames) == 1
    assert (frames[0].station_id, frames[0].seq, frames[0].message) == (station_id, seq, msg)
    assert type(frames[0].message) is type(msg)
    assert decoder.stats.frames_ok == 1 and decoder.stats.corrupt_frames == 0


@given(msgs=st.lists(messages, min_size=1, max_size=20), data=st.data())
@settings(max_examples=150, **RELAXED)
def test_chunk_splitting_anywhere_changes_nothing(msgs, data):
    stream, _ = _stream(msgs)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=30)))
    decoder = StreamDecoder()
    got = []
    for a, b in zip([0, *cuts], [*cuts, len(stream)]):
        got += decoder.feed(stream[a:b])
    assert [f.message for f in got] == msgs
    assert [f.seq for f in got] == list(range(1, len(msgs) + 1))
    assert decoder.stats.bytes_received == len(stream)
    assert decoder.stats.seq_gaps == decoder.stats.corrupt_frames == decoder.stats.bytes_discarded == 0


@given(msgs=st.lists(messages, min_size=3, max_size=25), data=st.data())
@settings(max_examples=200, **RELAXED)
def test_single_byte_damage_is_counted_exactly(msgs, data):
    """One non-zero-producing byte change in k frames: exactly k corrupt frames, k missing, nothing else lost.

    The first and last frames stay intact: a gap is only visible between two frames that did arrive."""
    stream, spans = _stream(msgs)
    damaged = sorted(data.draw(st.sets(st.integers(1, len(msgs) - 2), max_size=len(msgs) - 2)))
    buf = bytearray(stream)
    for i in damaged:
        start, end = spans[i]
        pos = data.draw(st.integers(start, end - 2))             # never the delimiter
        flip = data.draw(st.integers(1, 255).filter(lambda x, b=buf[pos]: b ^ x != 0))
        buf[pos] ^= flip
    decoder = StreamDecoder()
    got = decoder.feed(bytes(buf))
    intact = [m for i, m in enumerate(msgs) if i not in damaged]
    assert [f.message for f in got] == intact
    s = decoder.stats
    assert s.corrupt_frames == len(damaged)
    assert s.seq_gaps == len(damaged) and s.gaps_by_station.get(7, 0) == len(damaged)
    assert s.bytes_discarded == sum(spans[i][1] - spans[i][0] - 1 for i in damaged)
    assert s.frames_ok == len(intact)


@st.composite
def _damage(draw, length: int):
    kind = draw(st.sampled_from(["flip", "delete", "insert", "truncate_tail"]))
    pos = draw(st.integers(0, length))
    if kind == "flip":
        return kind, min(pos, length - 1), draw(st.integers(1, 255))
    if kind == "delete":
        return kind, pos, draw(st.integers(1, 12))
    if kind == "insert":
        return kind, pos, draw(st.binary(min_size=1, max_size=40))
    return kind, pos, None


@given(msgs=st.lists(messages, min_size=1, max_size=15), data=st.data())
@settings(max_examples=150, **RELAXED)
def test_random_damage_never_crashes_and_keeps_every_untouched_frame(msgs, data):
    """Flip / delete / insert / truncate anywhere, then chunk anywhere: every frame whose bytes and both
    delimiters survive unaltered and adjacent is still decoded, in order, and nothing is invented."""
    stream, spans = _stream(msgs)
    ops = data.draw(st.lists(_damage(len(stream)), max_size=6))
    buf = bytearray(stream)
    origin: list[int | None] = list(range(len(stream)))    # original index of every byte in buf; None = foreign
    for kind, pos, arg in ops:
        pos = min(pos, len(buf))
        if kind == "flip" and pos < len(buf):
            buf[pos] ^= arg
            origin[pos] = None
        elif kind == "delete":
            del buf[pos:pos + arg], origin[pos:pos + arg]
        elif kind == "insert":
            buf[pos:pos] = arg
            origin[pos:pos] = [None] * len(arg)
        elif kind == "truncate_tail":
            del buf[pos:], origin[pos:]
    where = {o: k for k, o in enumerate(origin) if o is not None}
    intact = []
    for i, (a, b) in enumerate(spans):
        first = a - 1 if a > 0 else a                       # include the previous frame's delimiter
        ks = [where.get(o) for o in range(first, b)]
        ok = None not in ks and all(ks[j + 1] == ks[j] + 1 for j in range(len(ks) - 1))
        intact.append(ok and (a > 0 or ks[0] == 0))
    cuts = sorted(data.draw(st.lists(st.integers(0, len(buf)), max_size=10)))
    decoder = StreamDecoder()
    got = []
    for a, b in zip([0, *cuts], [*cuts, len(buf)]):
        got += decoder.feed(bytes(buf[a:b]))
    everything = [(i + 1, m) for i, m in enumerate(msgs)]
    expected = [p for p, ok in zip(everything, intact) if ok]
    got_pairs = [(f.seq, f.message) for f in got]
    assert [p for p in got_pairs if p in expected] == expected
    assert all(p in everything for p in got_pairs), "decoder invented a frame"
    assert decoder.stats.bytes_received == len(buf)


def test_garbage_between_frames_is_counted_and_skipped():
    msgs = [ClockSync(i, i, 0) for i in range(5)]
    frames = [encode(m, 1, i + 1) for i, m in enumerate(msgs)]
    garbage = bytes([0x55] * 17) + b"\x00" + bytes([0xAA, 0x01, 0x02]) + b"\x00"
    decoder = StreamDecoder()
    got = decoder.feed(b"\x00" + frames[0] + garbage + b"".join(frames[1:]))
    assert [f.message for f in got] == msgs
    assert decoder.stats.corrupt_frames == 2
    assert decoder.stats.bytes_discarded == 20
    assert decoder.stats.seq_gaps == 0


def test_overlong_run_without_delimiter_is_dropped_and_next_frame_survives():
    decoder = StreamDecoder()
    junk = bytes([0x41]) * (3 * MAX_ENCODED_FRAME_BYTES)
    got = []
    for k in range(0, len(junk), 1000):
        got += decoder.feed(junk[k:k + 1000])
    assert decoder.stats.length_errors == 1
    got += decoder.feed(b"\x00" + encode(ClockSync(1, 2, 3), 1, 1))
    assert [f.message for f in got] == [ClockSync(1, 2, 3)]
    assert decoder.stats.bytes_discarded == len(junk)


def test_unknown_type_and_version_are_counted_not_returned():
    good = encode(ClockSync(1, 1, 0), 4, 10)
    unknown = frame_payload(0x7E, b"\x01\x02", station_id=4, seq=11)
    future = frame_payload(MessageType.CLOCK_SYNC, b"\x00" * 10, 4, 12, version=9)
    after = encode(ClockSync(3, 3, 0), 4, 13)
    decoder = StreamDecoder()
    got = decoder.feed(good + unknown + future + after)
    assert [f.message for f in got] == [ClockSync(1, 1, 0), ClockSync(3, 3, 0)]
    assert decoder.stats.unknown_types == 1 and decoder.stats.unsupported_version == 1
    # the unknown-type frame consumed seq 11 legitimately; the future-version frame (12) is not trusted
    assert decoder.stats.seq_gaps == 1


DATA = Path(__file__).parent / "data"


def test_version_1_station_stream_still_decodes():
    """Bytes a version-1 station sent (recorded before version 2 existed) decode exactly as then: every frame,
    no errors, accelerations only, the same counts the station's ground truth holds."""
    data = (DATA / "station_v1_1s2.bin").read_bytes()
    truth = np.load(DATA / "station_v1_1s2_truth.npz")
    decoder = StreamDecoder()
    frames = decoder.feed(data)
    assert decoder.stats.corrupt_frames == decoder.stats.unsupported_version == decoder.stats.unknown_types == 0
    assert decoder.stats.malformed_payloads == decoder.stats.seq_gaps == 0
    batches = [f.message for f in frames if isinstance(f.message, SampleBatch)]
    assert batches and all(b.quat_q14 is None and b.gyro_counts is None for b in batches)
    assert all(b.quat_wxyz() is None and b.gyro_rps() is None for b in batches)
    sensor = np.repeat([b.sensor_id for b in batches], [b.n_samples for b in batches])
    counter = np.concatenate([b.first_sample_counter + np.arange(b.n_samples) for b in batches])
    got, want = np.lexsort((counter, sensor)), np.lexsort((truth["counter"], truth["sensor_id"]))
    np.testing.assert_array_equal(np.concatenate([b.samples for b in batches])[got], truth["counts"][want])
    np.testing.assert_array_equal(sensor[got], truth["sensor_id"][want])


def test_frame_versions_and_motion_batch_only_in_version_2():
    """Old-layout frames keep header version 1 (a version-1 host reads them); a MOTION_BATCH is version 2, and a
    frame claiming type MOTION_BATCH under version 1 is an unknown type there."""
    samples = np.zeros((2, 3), np.int16)
    plain = SampleBatch(1, 0, 0, 0, 2560000, 1.0, samples)
    motion = SampleBatch(1, 0, 0, 0, 2560000, 1.0, samples, np.full((2, 4), 8192, np.int16))
    assert _body(encode(plain, 1, 0))[0] == 1 and _body(encode(ClockSync(1, 1, 0), 1, 0))[0] == 1
    assert _body(encode(motion, 1, 0))[:2] == bytes([2, MessageType.MOTION_BATCH])
    payload = _body(encode(motion, 1, 0))[10:-4]
    decoder = StreamDecoder()
    assert decoder.feed(frame_payload(MessageType.MOTION_BATCH, payload, 1, 0, version=1)) == []
    assert decoder.stats.unknown_types == 1
    assert decoder.feed(frame_payload(MessageType.MOTION_BATCH, payload, 1, 1))[0].message == motion


def test_motion_batch_values():
    """Q2.14 quaternions come out as unit quaternions (an all-zero one = no value = NaN), gyro counts x scale."""
    q = np.array([[16384, 0, 0, 0], [0, 0, 0, 0], [11585, 0, 0, 11585]], np.int16)
    gyro = np.array([[1, -2, 3], [0, 0, 0], [32767, 0, -32767]], np.int16)
    scale = float(np.float32(np.radians(2000) / 32767))
    batch = StreamDecoder().feed(encode(SampleBatch(2, 0, 5, 9, 2560000, 1.0, np.zeros((3, 3), np.int16), q, gyro,
                                                    scale), 3, 0))[0].message
    want_q = np.array([[1, 0, 0, 0], [np.nan] * 4, [np.sqrt(0.5), 0, 0, np.sqrt(0.5)]])
    np.testing.assert_allclose(batch.quat_wxyz(), want_q, atol=1e-12)
    np.testing.assert_allclose(batch.gyro_rps(), gyro * scale)
    assert batch.gyro_rps()[2, 0] == pytest.approx(np.radians(2000), rel=1e-6)


def test_malformed_motion_batch_is_counted():
    good = SampleBatch(0, 0, 0, 0, 2560000, 1.0, np.zeros((4, 3), np.int16), None, np.zeros((4, 3), np.int16), 0.01)
    payload = _body(encode(good, 1, 0))[10:-4]
    unknown_bit = payload[:20] + bytes([payload[20] | 0x80]) + payload[21:]
    decoder = StreamDecoder()
    for bad in (payload[:-6], unknown_bit, payload + b"\x00" * 8):
        assert decoder.feed(frame_payload(MessageType.MOTION_BATCH, bad, 1, 0)) == []
    assert decoder.stats.malformed_payloads == 3
    with pytest.raises(ValueError, match="gyro_scale_rps_per_lsb"):
        encode(SampleBatch(0, 0, 0, 0, 1, 1.0, np.zeros((1, 3), np.int16), None, np.zeros((1, 3), np.int16)), 1, 0)
    with pytest.raises(ValueError, match=r"quat_q14 must be \(1, 4\)"):
        encode(SampleBatch(0, 0, 0, 0, 1, 1.0, np.zeros((1, 3), np.int16), np.zeros((2, 4), np.int16)), 1, 0)


def test_malformed_payload_with_valid_crc_is_counted():
    payload = pack_sample_batch(SampleBatch(0, 0, 0, 0, 2560000, 1.0, np.zeros((4, 3), np.int16)))
    frame = frame_payload(MessageType.SAMPLE_BATCH, payload[:-6], station_id=1, seq=1)
    decoder = StreamDecoder()
    assert decoder.feed(frame) == []
    assert decoder.stats.malformed_payloads == 1


def test_sequence_gaps_wrap_and_reboot():
    decoder = StreamDecoder()
    hello = Hello((1, 0, 0), 1, 2, 1_000_000, (100,), (12,), ())
    seqs = [2**32 - 2, 2**32 - 1, 0, 3]                       # wrap is not a gap; 0 -> 3 misses 1, 2
    for s in seqs:
        decoder.feed(encode(ClockSync(s, s, 0), 5, s))
    assert decoder.stats.seq_gaps == 2 and decoder.stats.seq_resets == 0
    decoder.feed(encode(hello, 5, 0))                         # reboot: HELLO at seq 0 re-anchors silently
    decoder.feed(encode(ClockSync(0, 0, 0), 5, 1))
    assert decoder.stats.seq_gaps == 2 and decoder.stats.seq_resets == 0
    decoder.feed(encode(ClockSync(0, 0, 0), 6, 50))           # another station keeps its own sequence
    decoder.feed(encode(ClockSync(0, 0, 0), 6, 52))
    assert decoder.stats.gaps_by_station == {5: 2, 6: 1}


def test_encode_rejects_bad_messages():
    with pytest.raises(TypeError, match="not a protocol message"):
        encode("hello", 1, 1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="1..679 samples"):
        encode(SampleBatch(0, 0, 0, 0, 0, 1.0, np.zeros((0, 3), np.int16)), 1, 1)


@given(batch=sample_batches(max_samples=8))
@settings(**RELAXED)
def test_sample_batch_helpers(batch):
    np.testing.assert_array_equal(batch.acc_g(), batch.samples * batch.scale_g_per_lsb)
    ticks = batch.sample_ticks()
    assert ticks[0] == batch.first_sample_ticks
    np.testing.assert_allclose(np.diff(ticks), batch.period_ticks_q8 / 256)
    assert scale_for_range(12) == pytest.approx(12 / 32767, rel=1e-7)


def test_command_round_trip_through_station_direction():
    cmd = Command(command_id=65535, opcode=3, target=255, value=-5)
    assert StreamDecoder().feed(encode(cmd, 0, 0))[0].message == cmd


def _body(frame: bytes) -> bytes:
    from cobs.cobs import decode
    body = decode(frame[:-1])
    assert zlib.crc32(body[:-4]) == int.from_bytes(body[-4:], "little")
    return body


def test_payload_offsets_match_protocol_md():
    """Payload bytes written by hand from the PROTOCOL.md tables (offsets, widths, little-endian)."""
    import struct as s
    from firmware_protocol import Error, Nack, SensorInfo, SensorLink, Status

    samples = np.array([[1, -2, 3], [-32768, 32767, 0]], np.int16)
    batch = SampleBatch(sensor_id=4, flags=1, first_sample_counter=70000, first_sample_ticks=0xFFFFFFF0,
                        period_ticks_q8=2560000, scale_g_per_lsb=scale_for_range(8), samples=samples)
    want = (bytes([4, 1]) + s.pack("<H", 2) + s.pack("<I", 70000) + s.pack("<I", 0xFFFFFFF0)
            + s.pack("<I", 2560000) + s.pack("<f", 8 / 32767) + s.pack("<6h", 1, -2, 3, -32768, 32767, 0))
    body = _body(encode(batch, station_id=0x0102, seq=0x0A0B0C0D))
    assert body[:10] == bytes([1, 2, 0x02, 0x01, 0x0D, 0x0C, 0x0B, 0x0A]) + s.pack("<H", len(want))
    assert body[10:-4] == want

    hello = Hello((1, 2, 300), 0xC0DE0001, 77, 32768, (100, 200), (8, 16),
                  (SensorInfo(0, 1, 100, 8), SensorInfo(5, 1, 200, 16)))
    want = (bytes([1, 2]) + s.pack("<H", 300) + s.pack("<III", 0xC0DE0001, 77, 32768) + bytes([2])
            + s.pack("<2H", 100, 200) + bytes([2, 8, 16, 2]) + bytes([0, 1]) + s.pack("<H", 100) + bytes([8])
            + bytes([5, 1]) + s.pack("<H", 200) + bytes([16]))
    assert _body(encode(hello, 1, 0))[10:-4] == want

    status = Status(0x03, 87, 4950, 123456, 42, 7, 2, (SensorLink(0, -61, 90), SensorLink(1, -70, 80)))
    want = (bytes([3, 87]) + s.pack("<H", 4950) + s.pack("<IIII", 123456, 42, 7, 2) + bytes([2])
            + bytes([0]) + s.pack("<b", -61) + bytes([90, 1]) + s.pack("<b", -70) + bytes([80]))
    assert _body(encode(status, 1, 0))[10:-4] == want

    assert _body(encode(Command(513, 3, 0xFF, -7), 1, 0))[10:-4] == s.pack("<HBBi", 513, 3, 255, -7)
    assert _body(encode(Nack(513, 3, 4), 1, 0))[10:-4] == bytes([1, 2, 3, 4])
    assert _body(encode(Error(1, "bad ∆"), 1, 0))[10:-4] == bytes([1, 0]) + "bad ∆".encode()

    quat = np.array([[16384, 0, -1, 2], [3, 4, 5, 6]], np.int16)
    gyro = np.array([[7, -8, 9], [-32767, 0, 1]], np.int16)
    motion = SampleBatch(4, 0, 70000, 5, 2560000, scale_for_range(8), samples, quat, gyro, 0.5)
    want = (bytes([4, 0]) + s.pack("<H", 2) + s.pack("<III", 70000, 5, 2560000) + s.pack("<f", 8 / 32767)
            + bytes([3, 0]) + s.pack("<f", 0.5) + s.pack("<6h", 1, -2, 3, -32768, 32767, 0)
            + s.pack("<8h", 16384, 0, -1, 2, 3, 4, 5, 6) + s.pack("<6h", 7, -8, 9, -32767, 0, 1))
    body = _body(encode(motion, 1, 0))
    assert body[:2] == bytes([2, 9]) and body[10:-4] == want
    gyro_only = SampleBatch(4, 0, 70000, 5, 2560000, scale_for_range(8), samples, None, gyro, 0.5)
    assert _body(encode(gyro_only, 1, 0))[10:-4] == want[:20] + bytes([2, 0]) + want[22:38] + want[-12:]
