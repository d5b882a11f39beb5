"""Message dataclasses of the base-station protocol (byte layouts in PROTOCOL.md).

Why plain ints for opcodes/reasons/codes (with IntEnum constants beside them): a station may NACK an opcode the
host does not know and a newer station may send reason codes an older host does not know; the decoder must carry
those values through instead of failing on an enum conversion.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum, IntFlag

import numpy as np

PROTOCOL_VERSION = 2
"""Newest protocol version this code reads and writes (PROTOCOL.md). Version 2 adds MOTION_BATCH."""
BASE_VERSION = 1
"""Header version of every frame whose layout version 1 already defines: a station that speaks version 2 still
sends those with version 1, so a version-1 host keeps reading everything it understands."""
SUPPORTED_VERSIONS = (1, 2)
QUAT_Q14_ONE = 16384
"""MOTION_BATCH quaternion components are i16 in Q2.14: 1.0 = 16384 (resolution 6e-5, 0.007 degrees)."""
BROADCAST_SENSOR = 0xFF
"""`Command.target` value meaning "every sensor"."""
PERIODIC_BEACON = 0
"""`ClockSync.echo_command_id` of an unsolicited beacon (host command ids are 1..65535)."""
INT16_FULL_SCALE = 32767


class MessageType(IntEnum):
    HELLO = 0x01
    SAMPLE_BATCH = 0x02
    CLOCK_SYNC = 0x03
    STATUS = 0x04
    COMMAND = 0x05
    ACK = 0x06
    NACK = 0x07
    ERROR = 0x08
    MOTION_BATCH = 0x09     # version 2: a SAMPLE_BATCH plus orientation and/or angular rate


class SensorKind(IntFlag):
    """HELLO sensor kind, a capability bit set (version 1 only ever sends 1)."""
    ACCELEROMETER = 0x01
    ORIENTATION = 0x02      # on-board fusion filter: sensor -> device earth quaternion (Z up, yaw per sensor)
    ANGULAR_RATE = 0x04     # 3-axis gyroscope, rad/s in the sensor frame


class MotionChannels(IntFlag):
    """MOTION_BATCH channel bits: which blocks follow the accelerations."""
    ORIENTATION = 0x01
    ANGULAR_RATE = 0x02


class Opcode(IntEnum):
    START_STREAMING = 1
    STOP_STREAMING = 2
    SET_RATE = 3            # value = sample rate, Hz
    SET_RANGE = 4           # value = full-scale range, g
    IDENTIFY = 5            # value = blink duration, ms
    ENTER_CALIBRATION = 6
    LEAVE_CALIBRATION = 7
    REQUEST_HELLO = 8
    REQUEST_STATUS = 9
    REQUEST_CLOCK_SYNC = 10


class NackReason(IntEnum):
    UNKNOWN_OPCODE = 1
    UNSUPPORTED_VALUE = 2   # rate/range not in the HELLO lists, negative duration
    UNKNOWN_SENSOR = 3
    INVALID_STATE = 4       # e.g. SET_RATE while streaming
    MALFORMED = 5           # COMMAND payload of the wrong length


class ErrorCode(IntEnum):
    BAD_FRAME = 1           # a host->station frame failed COBS/length/CRC
    UNSUPPORTED_VERSION = 2
    BUFFER_OVERFLOW = 3
    UNEXPECTED_MESSAGE = 4  # a station-only message type was sent to the station


class StationFlags(IntFlag):
    STREAMING = 0x01
    CALIBRATING = 0x02
    IDENTIFYING = 0x04


class BatchFlags(IntFlag):
    CALIBRATING = 0x01      # samples taken while the station was in calibration mode


def scale_for_range(range_g: int) -> float:
    """g per LSB for a +-range_g int16 sensor, rounded to float32 because that is what goes on the wire."""
    return float(np.float32(range_g / INT16_FULL_SCALE))


@dataclass(frozen=True, slots=True)
class SensorInfo:
    sensor_id: int
    kind: int
    rate_hz: int
    range_g: int


@dataclass(frozen=True, slots=True)
class Hello:
    """Capabilities, sent unsolicited as frame seq 0 after boot and on REQUEST_HELLO."""
    firmware_version: tuple[int, int, int]
    station_serial: int
    boot_id: int                         # random per boot: tells a station reset from a counter wrap
    tick_rate_hz: int                    # device clock of every `*_ticks` field (u32, wraps)
    supported_rates_hz: tuple[int, ...]
    supported_ranges_g: tuple[int, ...]
    sensors: tuple[SensorInfo, ...]


@dataclass(slots=True, eq=False)
class SampleBatch:
    """N consecutive samples of one sensor. Treat as read-only: it is the one message decoded tens of thousands
    of times a second, and a non-frozen dataclass constructs about 4x faster than a frozen one.

    Sample i was latched at device tick `first_sample_ticks + i * sample_period_ticks` (mod 2**32) and has
    per-sensor counter `first_sample_counter + i` (mod 2**32); a jump in the counter is a radio loss.
    """
    sensor_id: int
    flags: int
    first_sample_counter: int
    first_sample_ticks: int
    period_ticks_q8: int                 # sample period in 1/256 device ticks (exact for 32768 Hz / 100 Hz too)
    scale_g_per_lsb: float               # float32 on the wire
    samples: np.ndarray                  # (N, 3) int16 counts, x y z (decoded: a read-only view of the frame)
    # version 2 (MOTION_BATCH) only; None = the channel is not in this batch
    quat_q14: np.ndarray | None = None   # (N, 4) int16 w x y z in Q2.14, sensor -> device earth; all 0 = no value
    gyro_counts: np.ndarray | None = None  # (N, 3) int16 angular rate counts, sensor frame
    gyro_scale_rps_per_lsb: float = 0.0  # float32 on the wire; > 0 when gyro_counts is given

    @property
    def n_samples(self) -> int:
        return int(self.samples.shape[0])

    @property
    def sample_period_ticks(self) -> float:
        return self.period_ticks_q8 / 256.0

    def acc_g(self) -> np.ndarray:
        """(N, 3) float64 acceleration in g."""
        return self.samples.astype(np.float64) * self.scale_g_per_lsb

    def quat_wxyz(self) -> np.ndarray | None:
        """(N, 4) float64 unit quaternions (sensor -> device earth, Z up), NaN rows where the station had no
        value (an all-zero quaternion: filter not converged); None when the batch carries no orientation."""
        if self.quat_q14 is None:
            return None
        q = self.quat_q14.astype(np.float64)
        norm = np.linalg.norm(q, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(norm > 0, q / norm, np.nan)

    def gyro_rps(self) -> np.ndarray | None:
        """(N, 3) float64 angular rate in rad/s (sensor frame); None when the batch carries none."""
        if self.gyro_counts is None:
            return None
        return self.gyro_counts.astype(np.float64) * self.gyro_scale_rps_per_lsb

    def sample_ticks(self) -> np.ndarray:
        """(N,) float64 latch ticks of every sample, NOT wrapped (first + i * period): unwrap `first` yourself."""
        return self.first_sample_ticks + np.arange(self.n_samples) * self.sample_period_ticks

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, SampleBatch):
            return NotImplemented
        return (
            (self.sensor_id, self.flags, self.first_sample_counter, self.first_sample_ticks, self.period_ticks_q8,
             self.scale_g_per_lsb)
            == (other.sensor_id, other.flags, other.first_sample_counter, other.first_sample_ticks,
                other.period_ticks_q8, other.scale_g_per_lsb)
            and self.samples.shape == other.samples.shape
            and bool(np.array_equal(self.samples, other.samples))
            and _same_optional(self.quat_q14, other.quat_q14)
            and _same_optional(self.gyro_counts, other.gyro_counts)
            and (self.gyro_counts is None or self.gyro_scale_rps_per_lsb == other.gyro_scale_rps_per_lsb)
        )


def _same_optional(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return a.shape == b.shape and bool(np.array_equal(a, b))


@dataclass(frozen=True, slots=True)
class ClockSync:
    """Station clock at the moment the frame was queued for the USB link."""
    station_ticks: int
    beacon_counter: int
    echo_command_id: int = PERIODIC_BEACON


@dataclass(frozen=True, slots=True)
class SensorLink:
    sensor_id: int
    rssi_dbm: int
    battery_pct: int


@dataclass(frozen=True, slots=True)
class Status:
    flags: int                           # StationFlags
    battery_pct: int
    battery_mv: int
    uptime_ms: int
    buffered_samples: int                # taken by sensors, not yet delivered to the host
    radio_drops: int                     # sensor batches lost on the radio since boot
    crc_errors: int                      # host->station frames rejected since boot
    links: tuple[SensorLink, ...]


@dataclass(frozen=True, slots=True)
class Command:
    command_id: int                      # host token 1..65535, echoed in ACK/NACK
    opcode: int
    target: int = BROADCAST_SENSOR
    value: int = 0


@dataclass(frozen=True, slots=True)
class Ack:
    command_id: int
    opcode: int


@dataclass(frozen=True, slots=True)
class Nack:
    command_id: int
    opcode: int
    reason: int


@dataclass(frozen=True, slots=True)
class Error:
    code: int
    text: str


Message = Hello | SampleBatch | ClockSync | Status | Command | Ack | Nack | Error
