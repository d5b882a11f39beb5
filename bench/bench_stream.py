"""Cost of the one sample -> frame path (`engine.stream.StreamSynthesis`) against the engine it feeds.

Six sensors at 100 Hz (jittered) plus a 12 fps camera, 60 s, resampled to 30 Hz frames. Rows: the path alone
(a do-nothing engine) fed live in 100 ms batches as the console's worker is, the same fed offline in one pass
(as `courtside synthesize`), the path driving the real fixed-lag motion graph (shipped clips, lag 0.5 s), and
the path driving the OLNG (shipped-clip knowledge base without the walk 16_32, fed that walk's virtual
accelerometers at the 4 seed-003 sites, 100 Hz, 25 Hz frames), and the accelerometer-only HMM on that walk's
right-foot sensor, and the OLNG again with every sensor also streaming its orientation (through a realistic
6-axis filter's errors) and angular rate (issue 18); plus the path alone with orientation + rate on every sensor,
against the accelerations-only path in the same run. Every engine runs live (100 ms batches, as the console's
worker) and offline (one pass, as `courtside synthesize`) in the same process: the live / offline ratio shows
what the live path adds. Times are per frame; "x real time" is the frame period over the cost per frame (below 1
the engine falls behind a live stream even on an idle core: the console then says FALLING BEHIND; issue 21 asks
>= 2). CPU time (this process, all threads) is printed beside wall time because on a shared, loaded
machine wall time measures the queue for the CPU more than the code.

    nice -n 10 .venv/bin/python bench/bench_stream.py [--seconds 60]
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from engine.stream import RecordedStreams, StreamSynthesis, synthesize_streams


class NullEngine:
    def push(self, acc_g, pos_m=None, heading_rad=None, *, quat_wxyz=None, gyro_rps=None) -> list:
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


def with_orientation(rec: RecordedStreams) -> RecordedStreams:
    """The same streams, each sensor also turning (a unit quaternion per sample) with its angular rate."""
    samples = {}
    for k, (t, acc) in rec.samples.items():
        half = 0.5 * (1.0 + 0.1 * k) * (t - t[0])
        quat = np.c_[np.cos(half), np.sin(half), np.zeros((len(t), 2))]
        samples[k] = (t, acc, quat, np.tile([1.0 + 0.1 * k, 0.0, 0.0], (len(t), 1)))
    return RecordedStreams(samples, rec.camera, rec.started_t_host_s)


HELD_OUT = "16_32"  # a walk, left out of the OLNG knowledge base


def worn_streams(clip: str, sensor_names, seconds: float, orientations: bool = False) -> RecordedStreams:
    """Real motion for the engines that search on it: the clip's virtual accelerometers at ``sensor_names``,
    sampled at 100 Hz with jitter (looped to ``seconds``), no camera; with ``orientations`` each sensor also
    streams its quaternion (sensor -> device earth, a realistic 6-axis filter's errors) and angular rate."""
    from engine.mocap import load_clip, sample_clips, standard_placements, virtual_accelerometers, virtual_gyroscopes
    from engine.mocap.orientation import OrientationErrorModel, virtual_orientations

    motion = load_clip(sample_clips()[clip], fps=100.0)
    placements = standard_placements(motion.skeleton, list(sensor_names))
    acc = virtual_accelerometers(motion, placements)
    rng = np.random.default_rng(1)
    n = int(seconds * 100)
    t = 1000.0 + np.arange(n) / 100.0 + rng.uniform(0, 0.002, n)
    rows = np.arange(n) % len(acc)
    if not orientations:
        return RecordedStreams({k: (t, acc[rows, k]) for k in range(len(sensor_names))}, [], None)
    quats = OrientationErrorModel.realistic().apply(virtual_orientations(motion, placements), 100.0, rng)
    gyro = virtual_gyroscopes(motion, placements)
    return RecordedStreams({k: (t, acc[rows, k], quats[rows, k], gyro[rows, k]) for k in range(len(sensor_names))},
                           [], None)


def run_live(make, rec: RecordedStreams, rate_hz: float) -> tuple[float, float, int]:
    """(wall s, CPU s of this process, frames pushed) for the stream fed in 100 ms batches."""
    session = StreamSynthesis(make, list(rec.samples), rate_hz)
    t_end_all = max(s[0][-1] for s in rec.samples.values())
    cam = iter(rec.camera)
    pending = next(cam, None)
    t0, c0 = time.perf_counter(), time.process_time()
    for t_end in np.arange(1000.1, t_end_all + 0.1, 0.1):
        for key, (t, *values) in rec.samples.items():
            sl = slice(np.searchsorted(t, t_end - 0.1, "right"), np.searchsorted(t, t_end, "right"))
            session.add_samples(key, t[sl], *(v[sl] for v in values))
        while pending is not None and pending[0] <= t_end:
            session.add_camera(*pending)
            pending = next(cam, None)
        session.step()
    return time.perf_counter() - t0, time.process_time() - c0, session.stats.frames_in


def run_offline(make, rec: RecordedStreams, rate_hz: float) -> tuple[float, float, int]:
    """(wall s, CPU s, frames) for the same stream synthesised in one pass (as `courtside synthesize`)."""
    t0, c0 = time.perf_counter(), time.process_time()
    _, session = synthesize_streams(make, rec, list(rec.samples), rate_hz)
    return time.perf_counter() - t0, time.process_time() - c0, session.stats.frames_in


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--olng-seconds", type=float, default=20.0, help="stream length for the (slowest) OLNG rows")
    args = p.parse_args()
    rec = streams(args.seconds)
    path_live = run_live(NullEngine, rec, 30.0)
    path_offline = run_offline(NullEngine, rec, 30.0)
    oriented = run_live(NullEngine, with_orientation(rec), 30.0)

    from engine.stream.registry import adapter  # the console's default databases

    graph = adapter("motion-graph").shipped_spec()
    olng = adapter("olng").shipped_spec(exclude=(HELD_OUT,))  # the console's default for 4 worn sensors, 25 Hz
    hmm = adapter("hmm").shipped_spec(exclude=(HELD_OUT,))    # the console's 1-sensor default: acc-only HMM
    olng_rec = worn_streams(HELD_OUT, olng.sensor_names, min(args.seconds, args.olng_seconds))
    hmm_rec = worn_streams(HELD_OUT, hmm.sensor_names, args.seconds)
    engines = [("motion graph (lag 0.5 s)", lambda: graph.make(0.5), rec, graph.rate_hz),
               ("OLNG (4 sensors)", lambda: olng.make(0.5), olng_rec, olng.rate_hz),
               ("OLNG acc+orientation+gyro", lambda: olng.make(0.5),
                worn_streams(HELD_OUT, olng.sensor_names, min(args.seconds, args.olng_seconds), orientations=True),
                olng.rate_hz),
               ("HMM acc-only (1 sensor)", lambda: hmm.make(0.5), hmm_rec, hmm.rate_hz)]
    runs = [(name, run_live(make, r, hz), run_offline(make, r, hz), hz) for name, make, r, hz in engines]
    load = os.getloadavg()[0]
    print(f"stream bench: 6 sensors x 100 Hz + 12 fps camera, {args.seconds:g} s -> {path_live[2]} frames at 30 Hz, "
          f"load avg {load:.1f} on {os.cpu_count()} cores")
    base = 1e6 * path_live[1] / path_live[2]
    print(f"{'':40s}{'wall us/frame':>14s}{'CPU us/frame':>14s}{'vs path (CPU)':>15s}{'x real time (CPU)':>19s}")
    for name, (wall, cpu, n), hz in (("path alone, live 100 ms batches", path_live, 30.0),
                                     ("path alone, offline one pass", path_offline, 30.0),
                                     ("path alone, live, + orientation + rate", oriented, 30.0)):
        us = 1e6 * cpu / n
        print(f"{name:40s}{1e6 * wall / n:14.1f}{us:14.1f}{us / base:15.2f}{1e6 / hz / us:19.2f}")
    # "x real time" = frame period / CPU cost per frame: below 1 the engine cannot keep up with the stream even
    # with a core to itself (wall time on a loaded machine is worse); the issue-21 goal is >= 2 live
    print(f"\n{'engine (path included)':28s}{'live ms':>9s}{'offline ms':>11s}{'live/offline':>13s}"
          f"{'live x rt':>10s}{'offline x rt':>13s}{'live x rt (wall)':>17s}   (CPU ms per frame)")
    for name, (wall, cpu, n), (_, cpu_off, n_off), hz in runs:
        live_ms, off_ms = 1e3 * cpu / n, 1e3 * cpu_off / n_off
        print(f"{name:28s}{live_ms:9.2f}{off_ms:11.2f}{live_ms / off_ms:13.2f}{1e3 / hz / live_ms:10.2f}"
              f"{1e3 / hz / off_ms:13.2f}{1e3 / hz / (1e3 * wall / n):17.2f}")


if __name__ == "__main__":
    main()
