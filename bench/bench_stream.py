"""Cost of the one sample -> frame path (`engine.stream.StreamSynthesis`) against the engine it feeds.

Six sensors at 100 Hz (jittered) plus a 12 fps camera, 60 s, resampled to 30 Hz frames. Rows: the path alone
(a do-nothing engine) fed live in 100 ms batches as the console's worker is, the same fed offline in one pass
(as `courtside synthesize`), the path driving the real fixed-lag motion graph (shipped clips, lag 0.5 s), and
the path driving the OLNG (shipped-clip knowledge base, 4 sensors at 25 Hz). Times are per frame; the ratio
column is against the path's live run, measured in this process; "x real time" is the frame period over the
cost per frame (below 1 the engine falls behind a live stream: the console then says FALLING BEHIND).

    nice -n 10 .venv/bin/python bench/bench_stream.py [--seconds 60]
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from engine.stream import RecordedStreams, StreamSynthesis, synthesize_streams


class NullEngine:
    def push(self, acc_g, pos_m=None, heading_rad=None) -> list:
        return []

    def flush(self) -> list:
        return []


def streams(seconds: float, n_sensors: int = 6, seed: int = 0) -> RecordedStreams:
    rng = np.random.default_rng(seed)
    samples = {}
    for k in range(n_sensors):
        t = 1000.0 + np.cumsum(rng.uniform(0.008, 0.012, int(seconds * 100)))
        samples[k] = (t, np.c_[np.sin(3 * t + k), np.cos(5 * t), np.full(len(t), 1.0)] + rng.normal(0, 0.02, (len(t), 3)))
    tc = np.arange(1000.0, 1000.0 + seconds, 1 / 12)
    camera = [(float(x), [0.5 * (x - 1000.0), -5.0], None) for x in tc]
    return RecordedStreams(samples, camera, None)


def run_live(make, rec: RecordedStreams, rate_hz: float) -> tuple[float, int]:
    session = StreamSynthesis(make, list(rec.samples), rate_hz)
    t_end_all = max(t[-1] for t, _ in rec.samples.values())
    cam = iter(rec.camera)
    pending = next(cam, None)
    t0 = time.perf_counter()
    for t_end in np.arange(1000.1, t_end_all + 0.1, 0.1):
        for key, (t, a) in rec.samples.items():
            sl = slice(np.searchsorted(t, t_end - 0.1, "right"), np.searchsorted(t, t_end, "right"))
            session.add_samples(key, t[sl], a[sl])
        while pending is not None and pending[0] <= t_end:
            session.add_camera(*pending)
            pending = next(cam, None)
        session.step()
    return time.perf_counter() - t0, session.stats.frames_in


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--olng-seconds", type=float, default=20.0, help="stream length for the (slow) OLNG row")
    args = p.parse_args()
    rec = streams(args.seconds)
    rate = 30.0
    live_s, frames = run_live(NullEngine, rec, rate)
    t0 = time.perf_counter()
    _, session = synthesize_streams(NullEngine, rec, list(rec.samples), rate)
    offline_s = time.perf_counter() - t0

    from engine.stream.databases import shipped_graph_spec, shipped_olng_spec  # the console's defaults

    spec = shipped_graph_spec()
    graph_s, graph_frames = run_live(lambda: spec.make(0.5), rec, spec.rate_hz)
    olng = shipped_olng_spec()  # the console's `--engine olng` default: 4 sensors at 25 Hz
    olng_rec = streams(min(args.seconds, args.olng_seconds), n_sensors=len(olng.sensor_names))
    olng_s, olng_frames = run_live(lambda: olng.make(0.5), olng_rec, olng.rate_hz)
    load = os.getloadavg()[0]
    print(f"stream bench: 6 sensors x 100 Hz + 12 fps camera, {args.seconds:g} s -> {frames} frames at 30 Hz, "
          f"load avg {load:.1f} on {os.cpu_count()} cores")
    print(f"{'':44s}{'us/frame':>10s}{'ratio':>8s}{'x real time':>13s}")
    base = 1e6 * live_s / frames
    for name, seconds, n, rate in (("path alone, live 100 ms batches", live_s, frames, 30.0),
                                   ("path alone, offline one pass", offline_s, session.stats.frames_in, 30.0),
                                   ("path + motion graph (lag 0.5 s), live", graph_s, graph_frames, spec.rate_hz),
                                   ("path + OLNG (4 sensors, 25 Hz), live", olng_s, olng_frames, olng.rate_hz)):
        us = 1e6 * seconds / n
        # "x real time" = frame period / cost per frame: below 1 the engine cannot keep up with the stream
        print(f"{name:44s}{us:10.1f}{us / base:8.2f}{1e6 / rate / us:13.2f}")


if __name__ == "__main__":
    main()
