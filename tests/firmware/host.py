"""A minimal host for the firmware tests: reads a station through any byte transport, decodes, and runs
commands with retry (as the gateway would), plus comparisons against the emulator's ground truth."""
from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from firmware_protocol import Ack, Command, DecodedFrame, Nack, SampleBatch, StreamDecoder, encode
from firmware_protocol.emulator import BaseStation, Fate
from firmware_protocol.emulator.link import EmulatorLink


class Host:
    """`read(n)` returns whatever bytes are available (possibly b""), `write(bytes)` sends to the station."""

    def __init__(self, link: EmulatorLink, read: Callable[[], bytes], write: Callable[[bytes], object],
                 delivered: Callable[[], int] | None = None) -> None:
        self.link = link
        self.station: BaseStation = link.station
        self._read = read
        self._write = write
        self._delivered = delivered or (lambda: self.station.bytes_out)
        self.decoder = StreamDecoder()
        self.frames: list[DecodedFrame] = []
        self.bytes_read = 0
        self._next_id = 1
        self._sent = 0

    def drain(self, timeout_s: float = 5.0) -> None:
        """Read until every byte the station has emitted (and the transport delivered) has been decoded."""
        deadline = time.monotonic() + timeout_s
        while self.bytes_read < self._delivered():
            chunk = self._read()
            if chunk:
                self.bytes_read += len(chunk)
                self.frames += self.decoder.feed(chunk)
            elif time.monotonic() > deadline:
                raise TimeoutError(f"read {self.bytes_read} of {self._delivered()} bytes")

    def run(self, seconds: float, step_s: float = 0.1) -> None:
        for _ in range(round(seconds / step_s)):
            self.link.advance(step_s)
            self.drain()

    def send(self, data: bytes, timeout_s: float = 5.0) -> None:
        """Write bytes and wait until the station has received them."""
        self._write(data)
        self._sent += len(data)
        deadline = time.monotonic() + timeout_s
        while self.station.host_bytes_received < self._sent:
            if time.monotonic() > deadline:
                raise TimeoutError("station did not receive the command")
            time.sleep(0.001)

    def transact(self, opcode: int, value: int = 0, target: int = 0xFF, tries: int = 6) -> Ack | Nack:
        """Send a COMMAND and return its ACK/NACK, resending the same id when the reply was lost on the wire."""
        command_id = self._next_id
        self._next_id += 1
        for attempt in range(tries):
            start = len(self.frames)
            self.send(encode(Command(command_id, opcode, target, value), self.station.config.station_id, attempt))
            self.link.advance(0.01)
            self.drain()
            for f in self.frames[start:]:
                if isinstance(f.message, (Ack, Nack)) and f.message.command_id == command_id:
                    return f.message
        raise AssertionError(f"no reply to command {command_id} after {tries} tries")

    def messages(self, kind: type) -> list:
        return [f.message for f in self.frames if isinstance(f.message, kind)]


def decoded_samples(frames: list[DecodedFrame]) -> dict[str, np.ndarray]:
    """Every decoded sample as arrays sorted by (sensor, counter)."""
    batches = [f.message for f in frames if isinstance(f.message, SampleBatch)]
    n = np.array([b.n_samples for b in batches])
    out = {
        "sensor_id": np.repeat([b.sensor_id for b in batches], n),
        "counter": np.concatenate([b.first_sample_counter + np.arange(b.n_samples) for b in batches]),
        "ticks": np.concatenate([(b.first_sample_ticks + np.arange(b.n_samples) * b.period_ticks_q8 // 256)
                                 % 2**32 for b in batches]),
        "counts": np.concatenate([b.samples for b in batches]),
    }
    order = np.lexsort((out["counter"], out["sensor_id"]))
    return {k: v[order] for k, v in out.items()}


def assert_matches_ground_truth(frames: list[DecodedFrame], station: BaseStation, boot: int = 0) -> dict:
    """Every sample the station put on the wire undamaged was decoded bit-exactly, and nothing else was."""
    truth = station.truth.samples()
    sel = (truth.boot == boot)
    ok = sel & truth.delivered
    order = np.lexsort((truth.counter[ok], truth.sensor_id[ok]))
    got = decoded_samples(frames)
    np.testing.assert_array_equal(got["sensor_id"], truth.sensor_id[ok][order])
    np.testing.assert_array_equal(got["counter"], truth.counter[ok][order])
    np.testing.assert_array_equal(got["counts"], truth.counts[ok][order])
    np.testing.assert_array_equal(got["ticks"], truth.ticks[ok][order])
    return {int(f): int(np.sum(truth.fate[sel] == f)) for f in Fate}
