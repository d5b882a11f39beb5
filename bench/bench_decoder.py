"""Decoder throughput: `python bench/bench_decoder.py [--seconds S]`.

Streams are produced by the emulated station (1 kHz, 6 sensors, per batch size), fed to StreamDecoder in
4 KiB chunks (a typical serial read), and timed. Reported against the project's target load, 4 stations x 6
sensors x 1 kHz = 24 000 samples/s, and against a naive byte-at-a-time decoder (COBS state machine in
Python, per-sample struct unpacking) run on the same bytes in the same process. Rows marked `ori` stream
protocol-v2 MOTION_BATCHes (each sample also carries an orientation quaternion and an angular rate); the last
lines give their decoded samples/s over the accelerations-only row of the same batch size, same run.
"""
from __future__ import annotations

import argparse
import struct
import time
import zlib

from firmware_protocol import Command, Opcode, SampleBatch, StreamDecoder, encode
from firmware_protocol.emulator import BaseStation, StationConfig

TARGET_SAMPLES_PER_S = 4 * 6 * 1000
CHUNK_BYTES = 4096


class NaiveDecoder:
    """The obvious first implementation: one Python step per byte, one struct call per sample."""

    def __init__(self) -> None:
        self.samples = 0
        self.frames = 0
        self.errors = 0
        self._frame = bytearray()
        self._remaining = 0
        self._code = 0xFF
        self._frame_started = False

    def feed(self, chunk: bytes) -> None:
        for byte in chunk:
            if byte == 0:
                self._finish()
            elif self._remaining == 0:
                if self._code != 0xFF and self._frame_started:
                    self._frame.append(0)
                self._code = byte
                self._remaining = byte - 1
                self._frame_started = True
            else:
                self._frame.append(byte)
                self._remaining -= 1

    def _finish(self) -> None:
        body, self._frame = bytes(self._frame), bytearray()
        ok = self._remaining == 0 and len(body) >= 14
        self._remaining, self._code, self._frame_started = 0, 0xFF, False
        if not ok or zlib.crc32(body[:-4]) != struct.unpack_from("<I", body, len(body) - 4)[0]:
            self.errors += ok or bool(body)
            return
        self.frames += 1
        if body[1] == 0x02:
            n = struct.unpack_from("<H", body, 12)[0]
            for i in range(n):
                struct.unpack_from("<hhh", body, 30 + 6 * i)
            self.samples += n


def make_stream(batch: int, seconds: float, corruption: float = 0.0, orientation: bool = False) -> tuple[bytes, int]:
    """Bytes of one station streaming 6 sensors at 1 kHz, and the number of samples it put on the wire."""
    config = StationConfig(n_sensors=6, rate_hz=1000, batch_samples=batch, byte_corruption=corruption, seed=1,
                           orientation=orientation)
    station = BaseStation(config)
    station.write(encode(Command(1, Opcode.START_STREAMING), 1, 0))
    data = b"".join(station.advance(0.5) for _ in range(int(seconds / 0.5)))
    return data, sum(len(b.ticks) for b in station.truth.batches)


def time_decoder(decoder, data: bytes, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        d = decoder()
        t0 = time.process_time()
        for i in range(0, len(data), CHUNK_BYTES):
            d.feed(data[i:i + CHUNK_BYTES])
        best = min(best, time.process_time() - t0)
    return best


def decoded_samples(data: bytes) -> int:
    frames = StreamDecoder().feed(data)
    return sum(f.message.n_samples for f in frames if isinstance(f.message, SampleBatch))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seconds", type=float, default=10.0, help="emulated seconds per stream")
    args = p.parse_args(argv)

    rows = []
    cases = ((1, 0.0, False), (5, 0.0, False), (10, 0.0, False), (25, 0.0, False), (10, 0.001, False),
             (10, 0.0, True), (25, 0.0, True))
    for batch, corruption, orientation in cases:
        t0 = time.process_time()
        data, n_wire = make_stream(batch, args.seconds, corruption, orientation)
        emu_s = time.process_time() - t0
        n = decoded_samples(data)
        fast = time_decoder(StreamDecoder, data)
        naive_data = data[: len(data) // 10]                   # the naive decoder is slow: time 10 % of it
        naive = time_decoder(NaiveDecoder, naive_data, repeat=1) * len(data) / len(naive_data)
        rows.append((batch, corruption, orientation, len(data), n, n / fast, len(data) / fast / 1e6,
                     n / fast / TARGET_SAMPLES_PER_S, naive / fast, args.seconds / emu_s))

    print(f"StreamDecoder throughput ({args.seconds:g} s of 6 sensors x 1 kHz per row, {CHUNK_BYTES} B chunks, "
          f"best of 3, one core)")
    print(f"target load: 4 stations x 6 sensors x 1 kHz = {TARGET_SAMPLES_PER_S} samples/s\n")
    header = (f"{'batch':>5} {'corrupt':>7} {'ori':>3} {'bytes':>9} {'samples':>8} {'samples/s':>11} {'MB/s':>6} "
              f"{'x target':>8} {'x naive':>7} {'emu x rt':>8}")
    print(header)
    print("-" * len(header))
    for batch, corruption, orientation, nbytes, n, sps, mbps, x_target, x_naive, emu_rt in rows:
        print(f"{batch:>5} {corruption:>7.3%} {'ori' if orientation else '-':>3} {nbytes:>9} {n:>8} {sps:>11.0f} "
              f"{mbps:>6.1f} {x_target:>8.1f} {x_naive:>7.1f} {emu_rt:>8.1f}")
    plain = {r[0]: r[5] for r in rows if not r[1] and not r[2]}
    for r in rows:
        if r[2]:
            print(f"orientation + angular rate on, batch {r[0]}: {r[5] / plain[r[0]]:.2f} x the samples/s of "
                  "accelerations only")
    print("\nx target: decoded samples/s over the target load (goal >= 50).  x naive: speed-up over the "
          "byte-at-a-time decoder.\nemu x rt: emulated seconds produced per wall second by BaseStation "
          "(one station, 6 sensors, 1 kHz).")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
