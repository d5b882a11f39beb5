"""What really happened inside the emulated station, as numpy arrays, so tests and the gateway can score
time alignment and loss exactly.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np


class Fate(IntEnum):
    """What became of a sample (or of the batch that carried it)."""
    IN_FLIGHT = 0          # taken, not yet put on the USB wire
    DELIVERED = 1          # on the wire, frame bytes and its leading delimiter undamaged
    RADIO_DROPPED = 2      # batch lost between sensor and station
    WIRE_CORRUPTED = 3     # frame damaged on the USB wire (or its delimiter was)
    LOST_UNPLUGGED = 4     # in the station's buffers or the transport's queue when the cable was pulled


@dataclass(slots=True)
class BatchRecord:
    """One radio batch of one sensor (k samples)."""
    sensor_id: int
    boot: int
    first_counter: int
    ticks: np.ndarray          # (k,) int64 latched u32 values
    t_true_s: np.ndarray       # (k,) true sampling times
    acc_true_g: np.ndarray     # (k, 3) before noise and quantisation
    counts: np.ndarray         # (k, 3) int16 what the sensor quantised
    flags: int                 # BatchFlags at sampling time (calibration mode)
    quat_true_wxyz: np.ndarray | None = None  # (k, 4) orientation before quantisation (device earth), if streamed
    gyro_true_rps: np.ndarray | None = None   # (k, 3) angular rate before quantisation
    quat_q14: np.ndarray | None = None        # (k, 4) int16 what went on the wire
    gyro_counts: np.ndarray | None = None     # (k, 3) int16
    fate: Fate = Fate.IN_FLIGHT
    frame: int = -1            # index into the frame table once sent


@dataclass(slots=True)
class FrameRecord:
    seq: int
    boot: int
    msg_type: int
    t_sent_s: float
    byte_offset: int           # position of the frame's first byte in the station's output stream
    n_bytes: int               # including the trailing delimiter
    intact: bool = True
    batch: BatchRecord | None = None


@dataclass(frozen=True)
class SampleTruth:
    """Per-sample ground truth, M samples in the order they were taken per sensor (sensors interleaved by batch)."""
    sensor_id: np.ndarray      # (M,) int
    boot: np.ndarray           # (M,) int, 0 for the first power-up, +1 per replug
    counter: np.ndarray        # (M,) int64 per-sensor sample counter (unwrapped; wire value is mod 2**32)
    ticks: np.ndarray          # (M,) int64 latched u32 station ticks
    t_true_s: np.ndarray       # (M,) float64 true time the sample was taken
    acc_true_g: np.ndarray     # (M, 3) float64 true acceleration (before noise/quantisation)
    counts: np.ndarray         # (M, 3) int16 quantised values the sensor produced
    fate: np.ndarray           # (M,) int8 Fate
    frame: np.ndarray          # (M,) int64 frame index or -1
    quat_true_wxyz: np.ndarray | None = None  # (M, 4) device-earth orientation before quantisation (orientation on)
    gyro_true_rps: np.ndarray | None = None   # (M, 3) rad/s before quantisation

    @property
    def delivered(self) -> np.ndarray:
        return self.fate == Fate.DELIVERED


@dataclass(frozen=True)
class FrameTruth:
    seq: np.ndarray
    boot: np.ndarray
    msg_type: np.ndarray
    t_sent_s: np.ndarray
    byte_offset: np.ndarray
    n_bytes: np.ndarray
    intact: np.ndarray


@dataclass(frozen=True)
class BeaconTruth:
    """Every CLOCK_SYNC the station sent: true send time and the ticks it carried."""
    t_true_s: np.ndarray
    ticks: np.ndarray
    counter: np.ndarray
    boot: np.ndarray


@dataclass
class GroundTruthLog:
    """Append-only log kept by BaseStation; `samples()` / `frames()` / `beacons()` build the arrays."""
    batches: list[BatchRecord] = field(default_factory=list)
    frame_log: list[FrameRecord] = field(default_factory=list)
    beacon_log: list[tuple[float, int, int, int]] = field(default_factory=list)

    def samples(self) -> SampleTruth:
        b = self.batches
        if not b:
            z = np.zeros(0, np.int64)
            return SampleTruth(z, z, z, z, np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3), np.int16),
                               np.zeros(0, np.int8), z)
        k = np.array([len(r.ticks) for r in b])
        return SampleTruth(
            sensor_id=np.repeat([r.sensor_id for r in b], k),
            boot=np.repeat([r.boot for r in b], k),
            counter=np.concatenate([r.first_counter + np.arange(n) for r, n in zip(b, k)]).astype(np.int64),
            ticks=np.concatenate([r.ticks for r in b]),
            t_true_s=np.concatenate([r.t_true_s for r in b]),
            acc_true_g=np.concatenate([r.acc_true_g for r in b]),
            counts=np.concatenate([r.counts for r in b]),
            fate=np.repeat(np.array([int(r.fate) for r in b], np.int8), k),
            frame=np.repeat([r.frame for r in b], k).astype(np.int64),
            quat_true_wxyz=_stacked([r.quat_true_wxyz for r in b]),
            gyro_true_rps=_stacked([r.gyro_true_rps for r in b]),
        )

    def frames(self) -> FrameTruth:
        f = self.frame_log
        return FrameTruth(
            seq=np.array([r.seq for r in f], np.int64),
            boot=np.array([r.boot for r in f], np.int64),
            msg_type=np.array([r.msg_type for r in f], np.int64),
            t_sent_s=np.array([r.t_sent_s for r in f], np.float64),
            byte_offset=np.array([r.byte_offset for r in f], np.int64),
            n_bytes=np.array([r.n_bytes for r in f], np.int64),
            intact=np.array([r.intact for r in f], bool),
        )

    def beacons(self) -> BeaconTruth:
        a = np.array(self.beacon_log, dtype=np.float64).reshape(-1, 4)
        return BeaconTruth(a[:, 0], a[:, 1].astype(np.int64), a[:, 2].astype(np.int64), a[:, 3].astype(np.int64))


def _stacked(parts: list[np.ndarray | None]) -> np.ndarray | None:
    """The batches' optional channel concatenated, or None when no batch carries it (a station streams a channel
    for all its sensors from boot, or for none)."""
    return None if any(p is None for p in parts) else np.concatenate(parts)
