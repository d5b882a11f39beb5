"""A Shimmer3 (LogAndStream firmware) on a pseudo-terminal, speaking its Bluetooth serial protocol, so the
vendor's `pyshimmer` opens it exactly as it opens the device's rfcomm port.

Protocol (Shimmer LogAndStream firmware, as pyshimmer implements it): one command byte (+ arguments) from the
host; the device answers every command with the ACK byte 0xFF, followed by the response code and payload for
commands that have one:

=======================  =========  ===========================================================================
command                  code       response after 0xFF
=======================  =========  ===========================================================================
get firmware version     0x2E       0x2F + <HHBB firmware type (3 = LogAndStream), major, minor, release
enable status ACK        0xA3 + B   -
get device name          0x7B       0x7A + length byte + name
get all calibration      0x2C       0x2D + 84 bytes: offset (>hhh), sensitivity (>hhh), alignment (9 x int8, /100)
                                    for low-noise accel, gyro, magnetometer, wide-range accel
get sampling rate        0x03       0x04 + <H ticks of the 32768 Hz clock per sample
inquiry                  0x01       0x02 + <HIBB rate ticks, config, channel count, buffer size + channel ids
start / stop streaming   0x07/0x20  -
=======================  =========  ===========================================================================

While streaming, each sample is a data packet: 0x00, the 24-bit little-endian 32768 Hz device time stamp (wraps
every 512 s), then the enabled channels. This emulator streams the wide-range accelerometer (LSM303, channel ids
0x04-0x06, int16 little-endian) calibrated with offset 0, sensitivity 208 LSB per m/s² (±16 g) and an identity
alignment, and, with ``gyro_dps`` given, the MPU9150 gyroscope (channel ids 0x0A-0x0C, int16 big-endian, the
order the firmware sends them: after the wide-range accelerometer) calibrated with offset 0, sensitivity 65.5 LSB
per deg/s (stored x100, Shimmer's convention: 6550; ±500 deg/s) and an identity alignment, from its own drifting
crystal clock, in bursts. ``truth`` keeps every sample's true host time."""
from __future__ import annotations

import os
import select
import struct
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from .pty_device import PtyDeviceEmulator

CLOCK_HZ = 32768.0
SENSITIVITY_LSB_PER_MPS2 = 208
GRAVITY_MPS2 = 9.80665
WIDE_RANGE_CHANNELS = bytes([0x04, 0x05, 0x06])
GYRO_CHANNELS = bytes([0x0A, 0x0B, 0x0C])
GYRO_SENSITIVITY_X100 = 6550  # 65.5 LSB per deg/s


@dataclass
class ShimmerTruth:
    ticks: list[int] = field(default_factory=list)  # unwrapped device ticks
    host_s: list[float] = field(default_factory=list)
    acc_g: list[np.ndarray] = field(default_factory=list)  # as quantised on the wire
    gyro_dps: list[np.ndarray] = field(default_factory=list)  # as quantised on the wire (with gyro_dps)


def calibration_bytes() -> bytes:
    """84 bytes: four 21-byte sensor blocks (low-noise accel, gyro, magnetometer, wide-range accel); the gyro and
    the wide-range accelerometer are the ones used here."""
    identity = struct.pack(">9b", 100, 0, 0, 0, 100, 0, 0, 0, 100)
    block = struct.pack(">hhh", 0, 0, 0) + struct.pack(">hhh", *(3 * [SENSITIVITY_LSB_PER_MPS2])) + identity
    gyro = struct.pack(">hhh", 0, 0, 0) + struct.pack(">hhh", *(3 * [GYRO_SENSITIVITY_X100])) + identity
    return block + gyro + block * 2


class ShimmerEmulator(PtyDeviceEmulator):
    def __init__(self, name: str = "Shimmer3-A1B2", rate_hz: float = 102.4, acc_g: np.ndarray | None = None,
                 drift_ppm: float = -30.0, start_ticks: int = 16_700_000, burst: int = 4, seed: int = 0,
                 gyro_dps: np.ndarray | None = None) -> None:
        rng = np.random.default_rng(seed)
        self.name = name
        self.period_ticks = int(round(CLOCK_HZ / rate_hz))
        self.rate_hz = CLOCK_HZ / self.period_ticks
        self.acc_g = np.asarray(acc_g, float) if acc_g is not None else \
            np.array([0.0, 1.0, 0.0]) + rng.normal(0.0, 0.005, (1000, 3))
        self.gyro_dps = None if gyro_dps is None else np.asarray(gyro_dps, float)
        if self.gyro_dps is not None and self.gyro_dps.shape != self.acc_g.shape:
            raise ValueError(f"Shimmer emulator: gyro_dps {self.gyro_dps.shape} does not match acc_g {self.acc_g.shape}")
        self.channels = WIDE_RANGE_CHANNELS + (GYRO_CHANNELS if self.gyro_dps is not None else b"")
        self.drift_ppm, self.start_ticks, self.burst = drift_ppm, start_ticks, burst
        self.truth = ShimmerTruth()
        self.commands: list[int] = []
        self._streaming = threading.Event()
        super().__init__(self._commands, self._stream)

    def _read(self, n: int) -> bytes:
        out = b""
        while len(out) < n and not self._stop.is_set():
            ready, _, _ = select.select([self._master], [], [], 0.1)
            if ready:
                try:
                    out += os.read(self._master, n - len(out))
                except OSError:
                    self._stop.set()
        return out

    def _commands(self) -> None:
        rate = struct.pack("<H", self.period_ticks)
        while not self._stop.is_set():
            code = self._read(1)
            if not code:
                continue
            command = code[0]
            self.commands.append(command)
            if command == 0x2E:
                self._write(b"\xff\x2f" + struct.pack("<HHBB", 3, 0, 16, 0))
            elif command == 0xA3:
                self._read(1)
                self._write(b"\xff")
            elif command == 0x7B:
                name = self.name.encode()
                self._write(b"\xff\x7a" + bytes([len(name)]) + name)
            elif command == 0x2C:
                self._write(b"\xff\x2d" + calibration_bytes())
            elif command == 0x03:
                self._write(b"\xff\x04" + rate)
            elif command == 0x01:
                self._write(b"\xff\x02" + rate + struct.pack("<IBB", 0, len(self.channels), 1) + self.channels)
            elif command == 0x07:
                self._write(b"\xff")
                self._streaming.set()
            elif command == 0x20:
                self._streaming.clear()
                self._write(b"\xff")

    def _stream(self) -> None:
        while not self._stop.is_set() and not self._streaming.wait(0.1):
            pass
        t0 = time.monotonic()
        k = 0
        while not self._stop.is_set():
            packets = []
            for _ in range(self.burst):
                host = t0 + k * self.period_ticks / CLOCK_HZ / (1.0 + self.drift_ppm * 1e-6)
                ticks = self.start_ticks + k * self.period_ticks
                row = self._replay_row(k, host, self.rate_hz, len(self.acc_g))
                raw = np.round(self.acc_g[row] * GRAVITY_MPS2 * SENSITIVITY_LSB_PER_MPS2)
                raw = np.clip(raw, -32768, 32767).astype(int)
                k += 1
                self.truth.ticks.append(ticks)
                self.truth.host_s.append(host)
                self.truth.acc_g.append(raw / SENSITIVITY_LSB_PER_MPS2 / GRAVITY_MPS2)
                packet = b"\x00" + struct.pack("<I", ticks % (1 << 24))[:3] + struct.pack("<3h", *raw)
                if self.gyro_dps is not None:
                    gyro = np.round(self.gyro_dps[row] * GYRO_SENSITIVITY_X100 / 100.0)
                    gyro = np.clip(gyro, -32768, 32767).astype(int)
                    self.truth.gyro_dps.append(gyro * 100.0 / GYRO_SENSITIVITY_X100)
                    packet += struct.pack(">3h", *gyro)
                packets.append(packet)
            delay = host - time.monotonic()  # the burst leaves as its last sample latches
            if delay > 0:
                self._stop.wait(delay)
            if self._streaming.is_set():
                self._write(b"".join(packets))
