"""Payload layouts: one pack and one unpack function per message type (little-endian, see PROTOCOL.md).

Why `struct` plus numpy instead of a declarative library: the sample payload is the hot path, and
`np.frombuffer` turns it into an (N, 3) int16 view without a Python loop.
"""
from __future__ import annotations

import math
import struct
from collections.abc import Callable

import numpy as np

from engine.errors import CourtsideError

from .messages import (
    Ack,
    ClockSync,
    Command,
    Error,
    Hello,
    Message,
    MessageType,
    MotionChannels,
    Nack,
    SampleBatch,
    SensorInfo,
    SensorLink,
    Status,
)

MAX_PAYLOAD_BYTES = 4096
MAX_ERROR_TEXT_BYTES = 200

_HELLO_HEAD = struct.Struct("<BBHIII")       # fw major, minor, patch, serial, boot id, tick rate
_SENSOR_INFO = struct.Struct("<BBHB")        # id, kind, rate Hz, range g
_BATCH_HEAD = struct.Struct("<BBHIIIf")      # sensor, flags, n, first counter, first ticks, period q8, scale
_MOTION_TAIL = struct.Struct("<BBf")        # channels, reserved (0), gyro scale rad/s per LSB (after _BATCH_HEAD)
_CLOCK_SYNC = struct.Struct("<IIH")
_STATUS_HEAD = struct.Struct("<BBHIIIIB")    # flags, batt %, batt mV, uptime ms, buffered, drops, crc errs, n links
_SENSOR_LINK = struct.Struct("<BbB")         # id, rssi dBm, battery %
_COMMAND = struct.Struct("<HBBi")
_ACK = struct.Struct("<HB")
_NACK = struct.Struct("<HBB")
_ERROR_HEAD = struct.Struct("<H")

MAX_BATCH_SAMPLES = (MAX_PAYLOAD_BYTES - _BATCH_HEAD.size) // 6
_INT16_LE = np.dtype("<i2")
_XYZ_INT16_LE = np.dtype(("<i2", (3,)))          # one sample; frombuffer with it yields (N, 3) directly
_WXYZ_INT16_LE = np.dtype(("<i2", (4,)))
_KNOWN_CHANNELS = int(MotionChannels.ORIENTATION | MotionChannels.ANGULAR_RATE)  # an int: ~IntFlag drops bits
_MOTION_HEAD_BYTES = _BATCH_HEAD.size + _MOTION_TAIL.size
MAX_MOTION_BATCH_SAMPLES = (MAX_PAYLOAD_BYTES - _MOTION_HEAD_BYTES) // 20   # every channel: 6 + 8 + 6 bytes each


class PayloadError(CourtsideError, ValueError):
    """A payload whose bytes do not match its layout (raised by unpack_*, counted by the decoder)."""


def _u8_list(values: tuple[int, ...], fmt: str) -> bytes:
    return struct.pack(f"<B{len(values)}{fmt}", len(values), *values)


def pack_hello(m: Hello) -> bytes:
    major, minor, patch = m.firmware_version
    parts = [
        _HELLO_HEAD.pack(major, minor, patch, m.station_serial, m.boot_id, m.tick_rate_hz),
        _u8_list(m.supported_rates_hz, "H"),
        _u8_list(m.supported_ranges_g, "B"),
        struct.pack("<B", len(m.sensors)),
    ]
    parts += [_SENSOR_INFO.pack(s.sensor_id, s.kind, s.rate_hz, s.range_g) for s in m.sensors]
    return b"".join(parts)


def unpack_hello(p: bytes) -> Hello:
    major, minor, patch, serial, boot_id, tick_rate = _HELLO_HEAD.unpack_from(p, 0)
    pos = _HELLO_HEAD.size
    n_rates = p[pos]
    rates = struct.unpack_from(f"<{n_rates}H", p, pos + 1)
    pos += 1 + 2 * n_rates
    n_ranges = p[pos]
    ranges = struct.unpack_from(f"<{n_ranges}B", p, pos + 1)
    pos += 1 + n_ranges
    n_sensors = p[pos]
    pos += 1
    if len(p) != pos + n_sensors * _SENSOR_INFO.size:
        raise PayloadError(f"HELLO lists {n_sensors} sensors but has {len(p) - pos} sensor bytes")
    sensors = tuple(SensorInfo(*_SENSOR_INFO.unpack_from(p, pos + i * _SENSOR_INFO.size)) for i in range(n_sensors))
    return Hello((major, minor, patch), serial, boot_id, tick_rate, rates, ranges, sensors)


def _checked_block(name: str, values: np.ndarray, n: int, width: int) -> np.ndarray:
    values = np.asarray(values)
    if values.shape != (n, width):
        raise ValueError(f"SampleBatch.{name} must be ({n}, {width}), got {values.shape}")
    return values


def _batch_head(m: SampleBatch, limit: int) -> tuple[bytes, np.ndarray]:
    samples = np.asarray(m.samples)
    if samples.ndim != 2 or samples.shape[1] != 3:
        raise ValueError(f"SampleBatch.samples must be (N, 3), got {samples.shape}")
    if not 1 <= samples.shape[0] <= limit:
        raise ValueError(f"SampleBatch must hold 1..{limit} samples, got {samples.shape[0]}")
    head = _BATCH_HEAD.pack(m.sensor_id, m.flags, samples.shape[0], m.first_sample_counter, m.first_sample_ticks,
                            m.period_ticks_q8, m.scale_g_per_lsb)
    return head, samples


def pack_sample_batch(m: SampleBatch) -> bytes:
    """Version 1 SAMPLE_BATCH (accelerations only); `pack_motion_batch` when the batch has more channels."""
    head, samples = _batch_head(m, MAX_BATCH_SAMPLES)
    return head + samples.astype(_INT16_LE, copy=False).tobytes()


def pack_motion_batch(m: SampleBatch) -> bytes:
    """Version 2 MOTION_BATCH: the SAMPLE_BATCH head, a channel byte, the gyro scale, then one block per channel
    (accelerations, [orientation Q2.14], [angular rate]), each sample-major."""
    head, samples = _batch_head(m, MAX_MOTION_BATCH_SAMPLES)
    n = samples.shape[0]
    channels, blocks = 0, [samples.astype(_INT16_LE, copy=False).tobytes()]
    if m.quat_q14 is not None:
        channels |= MotionChannels.ORIENTATION
        blocks.append(_checked_block("quat_q14", m.quat_q14, n, 4).astype(_INT16_LE, copy=False).tobytes())
    if m.gyro_counts is not None:
        if not (math.isfinite(m.gyro_scale_rps_per_lsb) and m.gyro_scale_rps_per_lsb > 0):
            raise ValueError(f"SampleBatch.gyro_scale_rps_per_lsb must be > 0, got {m.gyro_scale_rps_per_lsb}")
        channels |= MotionChannels.ANGULAR_RATE
        blocks.append(_checked_block("gyro_counts", m.gyro_counts, n, 3).astype(_INT16_LE, copy=False).tobytes())
    scale = m.gyro_scale_rps_per_lsb if m.gyro_counts is not None else 0.0
    return head + _MOTION_TAIL.pack(int(channels), 0, scale) + b"".join(blocks)


def unpack_sample_batch(p: bytes) -> SampleBatch:
    sensor, flags, n, counter, ticks, period_q8, scale = _BATCH_HEAD.unpack_from(p, 0)
    if len(p) != _BATCH_HEAD.size + 6 * n or n == 0:
        raise PayloadError(f"SAMPLE_BATCH says {n} samples but carries {len(p) - _BATCH_HEAD.size} sample bytes")
    samples = np.frombuffer(p, dtype=_XYZ_INT16_LE, count=n, offset=_BATCH_HEAD.size)
    return SampleBatch(sensor, flags, counter, ticks, period_q8, scale, samples)


def unpack_motion_batch(p: bytes) -> SampleBatch:
    sensor, flags, n, counter, ticks, period_q8, scale = _BATCH_HEAD.unpack_from(p, 0)
    channels, reserved, gyro_scale = _MOTION_TAIL.unpack_from(p, _BATCH_HEAD.size)
    has_quat, has_gyro = bool(channels & MotionChannels.ORIENTATION), bool(channels & MotionChannels.ANGULAR_RATE)
    if channels & ~_KNOWN_CHANNELS or reserved:
        raise PayloadError(f"MOTION_BATCH has unknown channel bits 0x{channels:02x} or reserved byte {reserved}")
    if len(p) != _MOTION_HEAD_BYTES + n * (6 + 8 * has_quat + 6 * has_gyro) or n == 0:
        raise PayloadError(f"MOTION_BATCH says {n} samples (channels 0x{channels:02x}) but is {len(p)} bytes")
    pos = _MOTION_HEAD_BYTES
    samples = np.frombuffer(p, dtype=_XYZ_INT16_LE, count=n, offset=pos)
    pos += 6 * n
    quat = None
    if has_quat:
        quat = np.frombuffer(p, dtype=_WXYZ_INT16_LE, count=n, offset=pos)
        pos += 8 * n
    gyro = np.frombuffer(p, dtype=_XYZ_INT16_LE, count=n, offset=pos) if has_gyro else None
    return SampleBatch(sensor, flags, counter, ticks, period_q8, scale, samples, quat, gyro,
                       gyro_scale if has_gyro else 0.0)


def message_type_and_payload(message: Message) -> tuple[int, bytes]:
    """(message type, packed payload): a SampleBatch with orientation or angular rate is a MOTION_BATCH."""
    if isinstance(message, SampleBatch) and (message.quat_q14 is not None or message.gyro_counts is not None):
        return MessageType.MOTION_BATCH, pack_motion_batch(message)
    try:
        msg_type, pack = PACKERS[type(message)]
    except KeyError:
        raise TypeError(f"not a protocol message: {type(message).__name__}") from None
    return msg_type, pack(message)


def pack_clock_sync(m: ClockSync) -> bytes:
    return _CLOCK_SYNC.pack(m.station_ticks, m.beacon_counter, m.echo_command_id)


def unpack_clock_sync(p: bytes) -> ClockSync:
    return ClockSync(*_fixed(_CLOCK_SYNC, p, "CLOCK_SYNC"))


def pack_status(m: Status) -> bytes:
    head = _STATUS_HEAD.pack(m.flags, m.battery_pct, m.battery_mv, m.uptime_ms, m.buffered_samples, m.radio_drops,
                             m.crc_errors, len(m.links))
    return head + b"".join(_SENSOR_LINK.pack(s.sensor_id, s.rssi_dbm, s.battery_pct) for s in m.links)


def unpack_status(p: bytes) -> Status:
    *head, n_links = _STATUS_HEAD.unpack_from(p, 0)
    if len(p) != _STATUS_HEAD.size + n_links * _SENSOR_LINK.size:
        raise PayloadError(f"STATUS lists {n_links} links but is {len(p)} bytes long")
    links = tuple(SensorLink(*_SENSOR_LINK.unpack_from(p, _STATUS_HEAD.size + i * _SENSOR_LINK.size))
                  for i in range(n_links))
    return Status(*head, links)


def pack_command(m: Command) -> bytes:
    return _COMMAND.pack(m.command_id, m.opcode, m.target, m.value)


def unpack_command(p: bytes) -> Command:
    return Command(*_fixed(_COMMAND, p, "COMMAND"))


def pack_ack(m: Ack) -> bytes:
    return _ACK.pack(m.command_id, m.opcode)


def unpack_ack(p: bytes) -> Ack:
    return Ack(*_fixed(_ACK, p, "ACK"))


def pack_nack(m: Nack) -> bytes:
    return _NACK.pack(m.command_id, m.opcode, m.reason)


def unpack_nack(p: bytes) -> Nack:
    return Nack(*_fixed(_NACK, p, "NACK"))


def pack_error(m: Error) -> bytes:
    text = m.text.encode("utf-8")
    if len(text) > MAX_ERROR_TEXT_BYTES:
        raise ValueError(f"ERROR text is {len(text)} bytes; at most {MAX_ERROR_TEXT_BYTES}")
    return _ERROR_HEAD.pack(m.code) + text


def unpack_error(p: bytes) -> Error:
    if len(p) < _ERROR_HEAD.size:
        raise PayloadError(f"ERROR payload is {len(p)} bytes")
    (code,) = _ERROR_HEAD.unpack_from(p, 0)
    return Error(code, p[_ERROR_HEAD.size:].decode("utf-8", errors="replace"))


def _fixed(layout: struct.Struct, p: bytes, name: str) -> tuple:
    if len(p) != layout.size:
        raise PayloadError(f"{name} payload is {len(p)} bytes, expected {layout.size}")
    return layout.unpack(p)


PACKERS: dict[type, tuple[MessageType, Callable[..., bytes]]] = {
    Hello: (MessageType.HELLO, pack_hello),
    SampleBatch: (MessageType.SAMPLE_BATCH, pack_sample_batch),
    ClockSync: (MessageType.CLOCK_SYNC, pack_clock_sync),
    Status: (MessageType.STATUS, pack_status),
    Command: (MessageType.COMMAND, pack_command),
    Ack: (MessageType.ACK, pack_ack),
    Nack: (MessageType.NACK, pack_nack),
    Error: (MessageType.ERROR, pack_error),
}

UNPACKERS: dict[int, Callable[[bytes], Message]] = {
    MessageType.HELLO: unpack_hello,
    MessageType.SAMPLE_BATCH: unpack_sample_batch,
    MessageType.CLOCK_SYNC: unpack_clock_sync,
    MessageType.STATUS: unpack_status,
    MessageType.COMMAND: unpack_command,
    MessageType.ACK: unpack_ack,
    MessageType.NACK: unpack_nack,
    MessageType.ERROR: unpack_error,
}
"""Version-1 layouts; a version-2 frame may also be a MOTION_BATCH (`UNPACKERS_V2`)."""

UNPACKERS_V2: dict[int, Callable[[bytes], Message]] = {**UNPACKERS, MessageType.MOTION_BATCH: unpack_motion_batch}
