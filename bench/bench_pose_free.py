"""Calibration from motion alone (`calibrate_take(pose=none)`, docs/imu-import.md "From motion"), on held-out
Bandai-1 gesture contents: each content's clips chained into one take at 30 Hz, six virtual orientation sensors
strapped uniformly over all rotations, read through a magnetometer-aided filter (one north ± 4 deg) or a 6-axis
one (a north per sensor); the database is every other content (leave one content out), as `courtside evaluate
--session` does.

Per take: how far the segments' turns lie from following the pelvis's as the database's do
(`turn_north_offset_deg`) and what that test alone says (`TURN_NORTH_DEG`); with --solve, what `auto` decides
with the fit test too (`ONE_NORTH_MISFIT`), each strap's error after the solve it chose, and its seconds; with
--cost-at-truth too, per strap the one-north search's cost at the true strap minus at the solved one
(`one_north_strap_costs`, each set against its own pelvis strap): positive where the database likes the solved
strap better than the truth, so that no better search would find the truth.

    python bench/bench_pose_free.py --mocap-dir ../shared/mocap [--seeds 3] [--solve [--cost-at-truth]]
        [--filter 9-axis]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import engine.mocap as M  # noqa: E402
from engine.mocap import quaternions as quat  # noqa: E402
from engine.mocap.orientation import OrientationErrorModel, from_device_earth, virtual_orientations  # noqa: E402
from engine.mocap.take_calibration import (REFERENCE_SENSOR, TURN_NORTH_DEG, MotionPrior, PoseSpec,  # noqa: E402
                                          calibrate_take, one_north_strap_costs, turn_north_offset_deg)

FPS = 30.0
NAMES = list(M.SEED000_SENSORS)
CONTENTS = ("bow", "bye", "byebye", "guide", "respond", "call")
FILTERS = {"9-axis": OrientationErrorModel.magnetometer, "6-axis": OrientationErrorModel.realistic}


def strap_error_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(2 * np.arccos(np.minimum(1.0, np.abs(np.sum(a * b, axis=-1)))))


def content_orientations(mocap_dir: str) -> tuple[dict[str, list[np.ndarray]], M.Skeleton]:
    """Every Bandai-1 clip's six virtual sensor orientations (F, S, 4) at `FPS`, by content, and the first clip's
    skeleton (the one the calibration poses are built on)."""
    files = sorted(Path(mocap_dir, "bandai-namco-1", "data").glob("*.bvh"))
    by_content: dict[str, list[np.ndarray]] = {}
    for f in files:
        motion = M.resample(M.load_clip(f), FPS)
        by_content.setdefault(f.stem.split("_")[1], []).append(
            virtual_orientations(motion, M.standard_placements(motion.skeleton, NAMES)))
    return by_content, M.resample(M.load_clip(files[0]), FPS).skeleton


def leave_content_out(by_content: dict[str, list[np.ndarray]], content: str) -> MotionPrior:
    """The database of every other content, as `courtside evaluate --session` holds a content out."""
    return MotionPrior(np.concatenate([q for c, qs in by_content.items() if c != content for q in qs]), tuple(NAMES))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--mocap-dir", required=True, help="the shared mocap folder (holds bandai-namco-1/data)")
    p.add_argument("--seeds", type=int, default=3, help="strap and north draws per content and filter")
    p.add_argument("--solve", action="store_true", help="also calibrate each take and print its strap errors")
    p.add_argument("--cost-at-truth", action="store_true",
                   help="with --solve: also the search's cost at the true straps minus at the solved ones")
    p.add_argument("--filter", choices=sorted(FILTERS), action="append",
                   help="only these orientation filters (repeatable; default both)")
    args = p.parse_args()
    by_content, skeleton = content_orientations(args.mocap_dir)
    ref = NAMES.index(REFERENCE_SENSOR)
    print(f"{'content':<9}{'filter':<8}{'seed':>5}{'turn offset deg':>16}{'turns':>8}"
          + (f"{'auto':>8}{'strap errors deg (' + ', '.join(NAMES) + ')':>60}{'s':>6}" if args.solve else ""))
    for content in CONTENTS:
        prior = leave_content_out(by_content, content)
        truth = np.concatenate(by_content[content])
        for label, model in FILTERS.items():
            if args.filter and label not in args.filter:
                continue
            for seed in range(1, args.seeds + 1):
                rng = np.random.default_rng(seed)
                strap = quat.normalize(rng.normal(size=(len(NAMES), 4)))
                readings = model().apply(quat.multiply(truth, strap[None]), FPS, rng)
                offset = turn_north_offset_deg(from_device_earth(readings), NAMES, ref, prior)
                turns = "shared" if offset <= TURN_NORTH_DEG else "own"
                line = f"{content:<9}{label:<8}{seed:>5}{offset:>16.0f}{turns:>8}"
                if args.solve:
                    start = time.perf_counter()
                    solved = calibrate_take(readings, FPS, NAMES, skeleton, PoseSpec("none"), prior)
                    errors = strap_error_deg(solved.orientation.mount_wxyz, strap)
                    line += f"{solved.north:>8}{' '.join(f'{e:6.0f}' for e in errors):>60}{time.perf_counter() - start:>6.0f}"
                    if args.cost_at_truth:
                        gap = (one_north_strap_costs(readings, FPS, NAMES, prior, strap)
                               - one_north_strap_costs(readings, FPS, NAMES, prior, solved.orientation.mount_wxyz))
                        line += "   truth - solved cost: " + " ".join("  ref" if np.isnan(g) else f"{g:+5.2f}"
                                                                       for g in gap)
                print(line, flush=True)


if __name__ == "__main__":
    main()
