"""An x-IMU3 on a pseudo-terminal, speaking the device's documented serial protocol (ASCII mode), so the vendor's
own `ximu3` library opens it exactly as it opens the hardware.

What it speaks (x-IMU3 user manual / x-IMU3-API ``data_messages``, ``command_message``, ``ping_response``):

* data: the inertial message ``I,<timestamp us>,<gyro x,y,z deg/s>,<acc x,y,z g>\\r\\n`` at the configured rate,
  the time stamp from the device's own microsecond clock (here with an offset and a crystal error in ppm);
* commands: one JSON object per line; ``{"ping":null}`` is answered with ``{"ping":{"interface":"USB",
  "name":<device name>,"sn":<serial>}}``, any other key is echoed back with its value (the device's
  acknowledgement convention).

Messages are written in bursts, as USB delivers them. Every sample's true host time is kept (``truth``), so tests
score the gateway's clock alignment against it. ``loss`` drops samples (a Bluetooth link) to exercise the
statistics."""
from __future__ import annotations

import json
import os
import pty
import select
import threading
import time
import tty
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Ximu3Truth:
    device_us: list[int] = field(default_factory=list)
    host_s: list[float] = field(default_factory=list)
    acc_g: list[np.ndarray] = field(default_factory=list)
    dropped: int = 0


class Ximu3Emulator:
    """``acc_g`` (N, 3) g played at ``rate_hz`` in a loop (default: still, 1 g up + 0.005 g noise)."""

    def __init__(self, name: str = "x-IMU3", serial: str = "65577B49", rate_hz: float = 100.0,
                 acc_g: np.ndarray | None = None, drift_ppm: float = 40.0, offset_us: int = 123_456_789,
                 loss: float = 0.0, burst: int = 4, seed: int = 0) -> None:
        self.name, self.serial, self.rate_hz = name, serial, rate_hz
        rng = np.random.default_rng(seed)
        self._rng = rng
        self.acc_g = np.asarray(acc_g, float) if acc_g is not None else \
            np.array([0.0, 0.0, 1.0]) + rng.normal(0.0, 0.005, (1000, 3))
        self.drift_ppm, self.offset_us, self.loss, self.burst = drift_ppm, offset_us, loss, burst
        self.truth = Ximu3Truth()
        self.commands: list[dict] = []
        self._master, slave = pty.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self._slave = slave
        self._stop = threading.Event()
        self._threads = [threading.Thread(target=self._stream, daemon=True),
                         threading.Thread(target=self._answer, daemon=True)]

    def start(self) -> "Ximu3Emulator":
        for t in self._threads:
            t.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(2.0)
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> "Ximu3Emulator":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def _write(self, data: bytes) -> None:
        try:
            os.write(self._master, data)
        except OSError:
            self._stop.set()

    def _stream(self) -> None:
        t0 = time.monotonic()
        k = 0
        while not self._stop.is_set():
            lines = []
            for _ in range(self.burst):
                host = t0 + k / self.rate_hz
                device_us = int(self.offset_us + (host - t0) * 1e6 * (1.0 + self.drift_ppm * 1e-6))
                acc = self.acc_g[k % len(self.acc_g)]
                k += 1
                if self._rng.random() < self.loss:
                    self.truth.dropped += 1
                    continue
                self.truth.device_us.append(device_us)
                self.truth.host_s.append(host)
                self.truth.acc_g.append(acc)
                lines.append(f"I,{device_us},0.000000,0.000000,0.000000,{acc[0]:.6f},{acc[1]:.6f},{acc[2]:.6f}\r\n")
            delay = t0 + (k - 1) / self.rate_hz - time.monotonic()  # the burst leaves as its last sample latches
            if delay > 0:
                self._stop.wait(delay)
            self._write("".join(lines).encode())

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
                except json.JSONDecodeError:
                    continue
                if not isinstance(command, dict) or len(command) != 1:
                    continue
                self.commands.append(command)
                key, value = next(iter(command.items()))
                if key == "ping":
                    value = {"interface": "USB", "name": self.name, "sn": self.serial}
                self._write((json.dumps({key: value}) + "\r\n").encode())
