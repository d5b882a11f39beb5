"""Cost of the one sample -> frame path (`engine.stream.StreamSynthesis`) against the engine it feeds.

Six sensors at 100 Hz (jittered) plus a 12 fps camera, 60 s, resampled to 30 Hz frames. Rows: the path alone
(a do-nothing engine) fed live in 100 ms batches as the console's worker is, the same fed offline in one pass
(as `courtside synthesize`), and the path driving the real fixed-lag motion graph (shipped clips, lag 0.5 s).
Times are per frame; the ratio column is against the path's live run, measured in this process.

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
    args = p.parse_args()
    rec = streams(args.seconds)
    rate = 30.0
    live_s, frames = run_live(NullEngine, rec, rate)
    t0 = time.perf_counter()
    _, session = synthesize_streams(NullEngine, rec, list(rec.samples), rate)
    offline_s = time.perf_counter() - t0

    from engine.stream.databases import shipped_graph_spec  # the console's default database (cached)

    spec = shipped_graph_spec()
    graph_s, graph_frames = run_live(lambda: spec.make(0.5), rec, spec.rate_hz)
    load = os.getloadavg()[0]
    print(f"stream bench: 6 sensors x 100 Hz + 12 fps camera, {args.seconds:g} s -> {frames} frames at 30 Hz, "
          f"load avg {load:.1f} on {os.cpu_count()} cores")
    print(f"{'':44s}{'us/frame':>10s}{'ratio':>8s}")
    base = 1e6 * live_s / frames
    for name, seconds, n in (("path alone, live 100 ms batches", live_s, frames),
                             ("path alone, offline one pass", offline_s, session.stats.frames_in),
                             ("path + motion graph (lag 0.5 s), live", graph_s, graph_frames)):
        print(f"{name:44s}{1e6 * seconds / n:10.1f}{1e6 * seconds / n / base:8.2f}")


if __name__ == "__main__":
    main()
