"""How long `courtside calibrate --graph` takes to solve a take (engine.mocap.take_calibration.calibrate_take), on
bench_real_recording's simulated recordings of held-out Bandai gestures (six sensors strapped uniformly over all
rotations, a 70-degree A-pose held 1.5 s, 60 Hz), per take length and orientation filter, for the start pose found
from the take and for calibration from motion (`--pose none`) -- beside the wizard's N-pose solve
(`OrientationCalibration.from_still_pose`: one mean of the hold, no database) in the same process. Each solve
builds its database prior afresh (`MotionPrior.from_graph`: its densities are made lazily, on first use), as one
`calibrate` run does. Median of `--repeats` runs.

    nice .venv/bin/python bench/bench_calibrate_take.py --mocap-dir ../shared/mocap --graph b1.npz \\
        [--groups bow,guide] [--seconds 10,30,60] [--repeats 1]

Why it matters: calibration is run once per take, but the held pose's 6-axis solve screens twelve pelvis twists
with the whole solve after each (docs/engine-evaluation.md), and a user waits for it courtside.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.bench_real_recording import HOLD_S, NAMES, RATE_HZ, held_out_take, simulate_recording  # noqa: E402
from engine.graph.graph import MotionGraph  # noqa: E402
from engine.mocap.orientation_calibration import OrientationCalibration, pose_sensor_orientations  # noqa: E402
from engine.mocap.take_calibration import MotionPrior, PoseSpec, calibrate_take  # noqa: E402


def median_seconds(run, repeats: int) -> tuple[float, object]:
    """The median wall time of `repeats` calls of `run` and the last call's result."""
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--mocap-dir", required=True)
    p.add_argument("--pattern", default="bandai-namco-1/data/*.bvh")
    p.add_argument("--graph", required=True, help="graph of every clip the pattern matches")
    p.add_argument("--groups", default="bow,guide", help="contents held out and acted in the takes")
    p.add_argument("--seconds", default="10,30,60", help="take lengths (each the groups' clips chained)")
    p.add_argument("--repeats", type=int, default=1)
    args = p.parse_args()
    graph = MotionGraph.load(args.graph)
    lengths = [float(s) for s in args.seconds.split(",")]
    take, train, _ = held_out_take(Path(args.mocap_dir), args.pattern, graph, args.graph, args.groups.split(","),
                                   max(lengths))
    template = pose_sensor_orientations(train.skeleton, NAMES)
    n_hold = int(round(HOLD_S * RATE_HZ))
    print(f"held out: {args.groups} ({take.n_frames / take.fps:.0f} s available); median of {args.repeats}")
    print(f"{'take s':>6} {'filter':>6} {'pose':>6} {'north':>6} {'solve s':>8} {'N-pose solve ms':>16} "
          f"{'x N-pose':>9} {'s per take-minute':>18}")
    for filter_name in ("9axis", "6axis"):
        rec = simulate_recording(take, "apose:70", "random", filter_name, np.random.default_rng(0))
        for seconds in lengths:
            frames = n_hold + int(round(min(seconds, take.n_frames / take.fps) * RATE_HZ))
            readings = rec.quat_device[:frames]
            base_s, _ = median_seconds(lambda: OrientationCalibration.from_still_pose(readings[:n_hold], template),
                                       args.repeats)
            for pose in ("apose", "none"):
                solve_s, solved = median_seconds(lambda: calibrate_take(
                    readings, RATE_HZ, NAMES, train.skeleton, PoseSpec(pose), MotionPrior.from_graph(train)),
                    args.repeats)
                take_s = frames / RATE_HZ
                print(f"{take_s:6.1f} {filter_name:>6} {pose:>6} {solved.north:>6} {solve_s:8.2f} "
                      f"{base_s * 1e3:16.2f} {solve_s / base_s:9.0f} {solve_s / take_s * 60:18.1f}", flush=True)


if __name__ == "__main__":
    main()
