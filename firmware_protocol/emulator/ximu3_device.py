"""An x-IMU3 on a pseudo-terminal, speaking the device's serial protocol in binary mode (the factory default) or
ASCII mode, so the vendor's own `ximu3` library opens it exactly as it opens the hardware.

What it speaks (x-IMU3-API ``receiver.rs``, ``data_messages/*.rs``, ``command_message``, ``ping_response``; the
factory settings in x-IMU3-GUI ``DeviceSettings/Settings.json``: "Binary mode enabled" true, AHRS messages as
quaternions at the inertial message rate divisor, temperature at a slow rate of its own, here every fifth sample):

* data, ASCII mode: ``I,<timestamp us>,<gyro x,y,z deg/s>,<acc x,y,z g>\\r\\n``, ``Q,<us>,w,x,y,z\\r\\n``,
  ``T,<us>,<deg C>\\r\\n``;
* data, binary mode: the identifier ``0x80 + ASCII id`` (0xC9 inertial, 0xD1 quaternion, 0xD4 temperature), the
  little-endian u64 time stamp and float32 values, byte-stuffed (0xDB -> 0xDB 0xDD, 0x0A -> 0xDB 0xDC) and ended
  by 0x0A, so the library's line splitter never cuts a message inside its payload;
* the time stamps come from the device's own microsecond clock (here with an offset and a crystal error in ppm);
* commands (both modes): one JSON object per line; ``{"ping":null}`` is answered with ``{"ping":{"interface":
  "USB","name":<device name>,"sn":<serial>}}``, any other key is echoed back with its value (the device's
  acknowledgement convention).

Messages are written in bursts, as USB delivers them. Every sample's true host time is kept (``truth``), so tests
score the gateway's clock alignment against it. ``loss`` drops samples (a Bluetooth link) to exercise the
statistics."""
from __future__ import annotations

import json
import os
import select
import struct
import time
from dataclasses import dataclass, field

import numpy as np

from .pty_device import PtyDeviceEmulator


@dataclass
class Ximu3Truth:
    device_us: list[int] = field(default_factory=list)
    host_s: list[float] = field(default_factory=list)
    acc_g: list[np.ndarray] = field(default_factory=list)  # as sent (float32 in binary mode)
    gyro_dps: list[np.ndarray] = field(default_factory=list)  # as sent
    quat_wxyz: list[np.ndarray] = field(default_factory=list)  # as sent (sensor -> earth, Z up)
    dropped: int = 0
    dropped_us: list[int] = field(default_factory=list)  # device time stamps of the dropped samples
    escaped_bytes: int = 0  # binary mode: payload bytes that needed byte stuffing (0x0A, 0xDB)


BYTE_STUFFING = {0x0A: b"\xdb\xdc", 0xDB: b"\xdb\xdd"}
MODES = ("binary", "ascii")


def binary_message(ascii_id: str, timestamp_us: int, values) -> tuple[bytes, int]:
    """One binary-mode data message (id ``0x80 + ascii_id``, u64 time stamp, float32 values, stuffed, 0x0A) and
    the number of payload bytes that were escaped."""
    payload = bytes([0x80 + ord(ascii_id)]) + struct.pack(f"<Q{len(values)}f", timestamp_us, *values)
    escaped = sum(payload.count(b) for b in BYTE_STUFFING)
    for byte, escape in sorted(BYTE_STUFFING.items(), key=lambda kv: kv[0] != 0xDB):  # escape the escape first
        payload = payload.replace(bytes([byte]), escape)
    return payload + b"\n", escaped


def ascii_message(ascii_id: str, timestamp_us: int, values) -> bytes:
    return (",".join([ascii_id, str(timestamp_us)] + [f"{v:.6f}" for v in values]) + "\r\n").encode()


class Ximu3Emulator(PtyDeviceEmulator):
    """``acc_g`` (N, 3) g played at ``rate_hz`` in a loop (default: still, 1 g up + 0.005 g noise), with optional
    ``gyro_dps`` (N, 3) deg/s and ``quat_wxyz`` (N, 4) sensor -> earth (Z up) rows of the same samples (default: no
    rotation, and the tilt ``acc_g`` shows); ``mode`` ``"binary"`` (the device's default) or ``"ascii"``."""

    def __init__(self, name: str = "x-IMU3", serial: str = "65577B49", rate_hz: float = 100.0,
                 acc_g: np.ndarray | None = None, drift_ppm: float = 40.0, offset_us: int = 123_456_789,
                 loss: float = 0.0, burst: int = 4, seed: int = 0, mode: str = "binary",
                 gyro_dps: np.ndarray | None = None, quat_wxyz: np.ndarray | None = None) -> None:
        if mode not in MODES:
            raise ValueError(f"x-IMU3 emulator mode {mode!r}: expected one of {MODES}")
        self.name, self.serial, self.rate_hz, self.mode = name, serial, rate_hz, mode
        rng = np.random.default_rng(seed)
        self._rng = rng
        self.acc_g = np.asarray(acc_g, float) if acc_g is not None else \
            np.array([0.0, 0.0, 1.0]) + rng.normal(0.0, 0.005, (1000, 3))
        self.gyro_dps = np.zeros_like(self.acc_g) if gyro_dps is None else np.asarray(gyro_dps, float)
        self.quat_wxyz = np.array([_tilt_quaternion(a) for a in self.acc_g]) if quat_wxyz is None else \
            np.asarray(quat_wxyz, float)
        if self.gyro_dps.shape != self.acc_g.shape or self.quat_wxyz.shape != (len(self.acc_g), 4):
            raise ValueError(f"x-IMU3 emulator: gyro_dps {self.gyro_dps.shape} / quat_wxyz {self.quat_wxyz.shape} "
                             f"do not match acc_g {self.acc_g.shape}")
        self.drift_ppm, self.offset_us, self.loss, self.burst = drift_ppm, offset_us, loss, burst
        self.truth = Ximu3Truth()
        self.commands: list[dict] = []
        super().__init__(self._stream, self._answer)

    def _stream(self) -> None:
        t0 = time.monotonic()
        k = 0
        while not self._stop.is_set():
            lines = []
            for _ in range(self.burst):
                host = t0 + k / self.rate_hz
                device_us = int(self.offset_us + (host - t0) * 1e6 * (1.0 + self.drift_ppm * 1e-6))
                row = self._replay_row(k, host, self.rate_hz, len(self.acc_g))
                acc, gyro, quat = self.acc_g[row], self.gyro_dps[row], self.quat_wxyz[row]
                if self.mode == "binary":
                    acc, gyro, quat = (v.astype(np.float32).astype(float) for v in (acc, gyro, quat))
                k += 1
                if self._rng.random() < self.loss:
                    self.truth.dropped += 1
                    self.truth.dropped_us.append(device_us)
                    continue
                self.truth.device_us.append(device_us)
                self.truth.host_s.append(host)
                self.truth.acc_g.append(acc)
                self.truth.gyro_dps.append(gyro)
                self.truth.quat_wxyz.append(quat)
                lines += self._messages(k, device_us, acc, gyro, quat)
            delay = t0 + (k - 1) / self.rate_hz - time.monotonic()  # the burst leaves as its last sample latches
            if delay > 0:
                self._stop.wait(delay)
            self._write(b"".join(lines))

    def _messages(self, k: int, device_us: int, acc: np.ndarray, gyro_dps: np.ndarray, quat: np.ndarray
                  ) -> list[bytes]:
        """Sample ``k``'s messages as the device sends them by default: inertial, AHRS quaternion, now and then a
        temperature. The station must pick the inertial and quaternion messages out of this mix."""
        messages = [("I", (*gyro_dps, *acc)), ("Q", tuple(quat))]
        if k % 5 == 0:
            messages.append(("T", (24.5,)))
        if self.mode == "ascii":
            return [ascii_message(i, device_us, values) for i, values in messages]
        encoded = [binary_message(i, device_us, values) for i, values in messages]
        self.truth.escaped_bytes += sum(escaped for _, escaped in encoded)
        return [message for message, _ in encoded]

    def _answer(self) -> None:
        buffer = b""
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([self._master], [], [], 0.1)
                if not ready:
                    continue
                buffer += os.read(self._master, 4096)
            except OSError:
                return
            while b"\n" in buffer:
                line, buffer = buffer.split(b"\n", 1)
                try:
                    command = json.loads(line.strip() or b"null")
                except ValueError:  # not JSON, or not UTF-8 (line noise as a port opens): ignored like a device does
                    continue
                if not isinstance(command, dict) or len(command) != 1:
                    continue
                self.commands.append(command)
                key, value = next(iter(command.items()))
                if key == "ping":
                    value = {"interface": "USB", "name": self.name, "sn": self.serial}
                self._write((json.dumps({key: value}) + "\r\n").encode())


def _tilt_quaternion(acc_g: np.ndarray) -> np.ndarray:
    """The rotation sensor -> earth (Z up) that a still sensor reading ``acc_g`` has, with no turn about Z."""
    up = acc_g / (np.linalg.norm(acc_g) or 1.0)
    half = np.array([1.0 + up[2], up[1], -up[0], 0.0])  # rotation taking the sensor's up to z, unnormalised
    return half / (np.linalg.norm(half) or 1.0)
