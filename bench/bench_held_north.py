"""One north or one each from a held pose (`calibrate_take(north="auto")`, docs/imu-import.md "One north"): the
numbers behind `HELD_ONE_NORTH_FIT`, on held-out Bandai-1 gesture contents. Each content's clips are chained
into one take at 30 Hz after a 70-degree A-pose held 2 s (each segment 3 deg off the template), six virtual
orientation sensors strapped uniformly over all rotations, read through a magnetometer-aided filter (9-axis, one
north +- 4 deg) or a 6-axis one (a north per sensor); the database is every other content (leave one content
out), as `courtside evaluate --session` does.

Per take: whether the per-sensor solve's norths agree (`_norths_agree`), how much worse the one-north solve fits
the database than the per-sensor one (`_fit_gap`, the quantity `HELD_ONE_NORTH_FIT` bounds), what `auto`
decides, and the mean strap error of each solve. Then, per filter, the range of the gap over the takes whose own
norths disagree, and how many of them the fit test takes as one north.

    python bench/bench_held_north.py --mocap-dir ../shared/mocap [--seeds 6]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.bench_pose_free import (CONTENTS, FILTERS, FPS, NAMES, content_orientations,  # noqa: E402
                                   leave_content_out, strap_error_deg)
from engine.evaluation.simulate import random_rotations  # noqa: E402
from engine.mocap import quaternions as quat  # noqa: E402
from engine.mocap.orientation import from_device_earth  # noqa: E402
from engine.mocap.orientation_calibration import pose_sensor_orientations  # noqa: E402
from engine.mocap.take_calibration import (HELD_ONE_NORTH_FIT, PoseSpec, _fit_gap, _norths_agree,  # noqa: E402
                                          _Solution, _take_solver, calibrate_take)

HOLD_S = 2.0
ARM_DEG = 70.0
POSING_ERROR_DEG = 3.0


def solutions(solved) -> list[_Solution]:
    """A `TakeCalibration`'s sensors as the solver's solutions (strap matrix, yaw)."""
    cal = solved.orientation
    return [_Solution(quat.to_matrix(m), float(y)) for m, y in zip(cal.mount_wxyz, cal.yaw_rad)]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--mocap-dir", required=True, help="the shared mocap folder (holds bandai-namco-1/data)")
    p.add_argument("--seeds", type=int, default=6, help="strap, heading and north draws per content and filter")
    args = p.parse_args()
    by_content, skeleton = content_orientations(args.mocap_dir)
    apose = PoseSpec("apose")
    print(f"{'content':<9}{'filter':<8}{'seed':>5}{'agree':>7}{'fit gap':>9}{'auto':>8}"
          f"{'own strap mean deg':>20}{'one-north strap mean deg':>26}")
    gaps: dict[str, list[float]] = {label: [] for label in FILTERS}  # of the takes whose own norths disagree
    for content in CONTENTS:
        prior = leave_content_out(by_content, content)
        truth = np.concatenate(by_content[content])
        for label, model in FILTERS.items():
            for seed in range(1, args.seeds + 1):
                rng = np.random.default_rng(seed)
                strap = quat.normalize(rng.normal(size=(len(NAMES), 4)))
                held = pose_sensor_orientations(skeleton, NAMES, "apose", heading_rad=rng.uniform(-np.pi, np.pi),
                                                arm_deg=ARM_DEG)
                held = quat.multiply(random_rotations(rng, len(NAMES), np.radians(POSING_ERROR_DEG)), held)
                q = np.concatenate([np.repeat(held[None], int(HOLD_S * FPS), 0), truth])
                readings = model().apply(quat.multiply(q, strap[None]), FPS, rng)
                auto = calibrate_take(readings, FPS, NAMES, skeleton, apose, prior)
                other = calibrate_take(readings, FPS, NAMES, skeleton, apose, prior,
                                       north="own" if auto.north == "shared" else "shared")
                own, shared = (other, auto) if auto.north == "shared" else (auto, other)
                agree = _norths_agree(list(own.orientation.yaw_rad))
                solver = _take_solver(from_device_earth(readings), FPS, NAMES, prior, 300, spins=False)
                gap = _fit_gap(solver, solutions(shared), solutions(own))
                if not agree:
                    gaps[label].append(gap)
                print(f"{content:<9}{label:<8}{seed:>5}{'yes' if agree else 'no':>7}{gap:>+9.3f}{auto.north:>8}"
                      f"{strap_error_deg(own.orientation.mount_wxyz, strap).mean():>20.1f}"
                      f"{strap_error_deg(shared.orientation.mount_wxyz, strap).mean():>26.1f}", flush=True)
    for label, values in gaps.items():
        if values:
            within = sum(v <= HELD_ONE_NORTH_FIT for v in values)
            print(f"{label}: {len(values)} takes whose own norths disagree, fit gap {min(values):+.3f} .. "
                  f"{max(values):+.3f}; within HELD_ONE_NORTH_FIT ({HELD_ONE_NORTH_FIT}, one north): {within}")


if __name__ == "__main__":
    main()
