"""Run an emulated station through a `StationReader` in virtual time: hours of emulated time in minutes.

Why: the clock target (< 1 ms p99 after warm-up, +-100 ppm, 0-20 ms delivery jitter, 1 h) cannot be checked in
real time inside a test budget. Here the station advances in 10 ms steps; the host "reads" the link at random
instants (gaps uniform in [0, jitter_s]), each read returning every frame the station finished sending before
it, so every frame's delivery latency is in [0, jitter_s) and the byte order is preserved (a USB link is FIFO).
The reader's commands (HELLO request, START, 10 Hz clock probes) go back to the station at the current step,
exactly as over a real link. Errors are scored against the emulator's true sampling times.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from firmware_protocol.emulator import BaseStation, StationConfig
from gateway.station import SampleBlock, StationReader

HOST_EPOCH_S = 5000.0  # host monotonic time at emulator true time 0 (arbitrary, like a real boot)
STEP_S = 0.01


class _VirtualLink:
    """Host->station direction of the virtual link (the station->host bytes are fed by `run`)."""

    def __init__(self, station: BaseStation, source: str):
        self.station = station
        self.source = source

    def read(self, max_bytes: int) -> bytes:  # pragma: no cover - the thread is never started
        return b""

    def write(self, data: bytes) -> None:
        self.station.write(data)

    def close(self) -> None:
        pass


class _Collector:
    """Sink keeping only what scoring needs (sensor, counter, epoch, host time) to bound memory over hours."""

    def __init__(self) -> None:
        self.parts: list[tuple[int, int, np.ndarray, np.ndarray, float]] = []

    def on_samples(self, block: SampleBlock) -> None:
        self.parts.append((block.sensor, block.epoch, block.counter.astype(np.int64), block.t_host_s,
                           float(block.arrival_s[0])))

    def on_station_event(self, station: str, level: str, message: str, details: dict | None = None) -> None:
        pass


@dataclass
class VirtualRun:
    """Per delivered sample: time error (s, gateway time - truth) and age since its boot (s)."""

    error_s: np.ndarray
    age_s: np.ndarray
    naive_error_s: np.ndarray  # baseline: stamping each sample with its batch's host arrival time
    delivered: int  # samples the station delivered intact (ground truth)
    received: int  # samples the reader produced
    status: dict

    def error_after(self, warmup_s: float) -> np.ndarray:
        return np.abs(self.error_s[self.age_s > warmup_s])


def run_virtual_station(config: StationConfig, duration_s: float, jitter_s: float = 0.02, seed: int = 0,
                        **reader_options) -> VirtualRun:
    """Emulate ``duration_s`` of one station and score every sample's gateway time."""
    rng = np.random.default_rng(seed)
    station = BaseStation(config)
    sink = _Collector()
    reader = StationReader("virtual", sink, open_link=lambda source: _VirtualLink(station, source), **reader_options)
    reader.connect()
    next_read = 0.0
    n_frames = 0
    for _ in range(int(round(duration_s / STEP_S))):
        data = station.advance(STEP_S)
        frames = station.truth.frame_log[n_frames:]
        n_frames = len(station.truth.frame_log)
        if not data:
            continue
        base = station.bytes_out - len(data)
        if not frames:
            reader.feed(data, HOST_EPOCH_S + station.now_s)
            continue
        if frames[0].byte_offset > base:  # delimiter bytes before the first frame
            reader.feed(data[: frames[0].byte_offset - base], HOST_EPOCH_S + station.now_s)
        sent = np.array([f.t_sent_s for f in frames])
        i = 0
        while i < len(frames):
            while next_read < sent[i]:
                next_read += rng.uniform(0.0, jitter_s) if jitter_s > 0 else sent[i] - next_read
            j = i + int(np.searchsorted(sent[i:], next_read, side="right"))
            start = frames[i].byte_offset - base
            end = frames[j - 1].byte_offset - base + frames[j - 1].n_bytes
            reader.feed(data[start:end], HOST_EPOCH_S + next_read)
            i = j
    return _score(station, sink, reader)


def _score(station: BaseStation, sink: _Collector, reader: StationReader) -> VirtualRun:
    truth = station.truth.samples()
    # truth rows are unique per (boot, sensor, counter): index them with one integer key
    key_truth = (truth.boot * 256 + truth.sensor_id) * (1 << 40) + truth.counter
    order = np.argsort(key_truth)
    boot_start = {int(b): float(truth.t_true_s[truth.boot == b].min()) for b in np.unique(truth.boot)}
    errors, ages, naive = [], [], []
    for sensor, epoch, counter, t_host, arrival_s in sink.parts:
        keys = (epoch * 256 + sensor) * (1 << 40) + counter
        rows = order[np.searchsorted(key_truth, keys, sorter=order)]
        if not np.array_equal(key_truth[rows], keys):
            raise AssertionError("reader produced a sample the station never took")
        t_true = truth.t_true_s[rows]
        errors.append(t_host - (HOST_EPOCH_S + t_true))
        naive.append(arrival_s - (HOST_EPOCH_S + t_true))
        ages.append(t_true - np.array([boot_start[epoch]]))
    error, age, naive_error = (np.concatenate(x) if x else np.zeros(0) for x in (errors, ages, naive))
    return VirtualRun(error, age, naive_error, int(truth.delivered.sum()), len(error), reader.status())
