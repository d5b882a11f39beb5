"""One north or one each from a held pose (`calibrate_take(north="auto")`, docs/imu-import.md "One north"): the
numbers behind `HELD_TURN_NORTH_DEG` and `HELD_ONE_NORTH_FIT`, on held-out Bandai-1 gesture contents. Each
content's clips are chained into one take at 30 Hz after a 70-degree A-pose held 2 s (each segment 3 deg off the
template), six virtual orientation sensors strapped uniformly over all rotations, read through a
magnetometer-aided filter (9-axis, one north +- 4 deg) or a 6-axis one (a north per sensor); the database is every
other content (leave one content out), as `courtside evaluate --session` does.

Per take: whether the per-sensor solve's norths agree (`_norths_agree`), how much worse the one-north solve fits
the database than the per-sensor one (`_fit_gap`, the quantity `HELD_ONE_NORTH_FIT` bounds), how far the
sensors' turns lie from following the pelvis's as in one earth frame (`turn_north_offset_deg`, bounded by
`HELD_TURN_NORTH_DEG`), what `auto` decides, the mean strap error of each solve and the own solve's pelvis strap
error. Then, per filter, the range of the turn offset, that of the fit gap over the takes whose turns pass and
whose own norths disagree, how many takes `auto` took as one north, and on how many the own solve turned the
pelvis strap round (over 90 deg off: a north per sensor sees its twist only in its tilts).

    python bench/bench_held_north.py --mocap-dir ../shared/mocap [--seeds 6] [--first-seed 1] [--seconds 20]
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
from engine.mocap.take_calibration import (HELD_TURN_NORTH_DEG, PoseSpec, _fit_gap, _norths_agree,  # noqa: E402
                                          _Solution, _take_solver, calibrate_take, turn_north_offset_deg)

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
    p.add_argument("--first-seed", type=int, default=1, help="the first draw's seed (more draws: --first-seed 7)")
    p.add_argument("--seconds", type=float, default=None, help="only each content's first SECONDS (default: all)")
    args = p.parse_args()
    by_content, skeleton = content_orientations(args.mocap_dir)
    apose = PoseSpec("apose")
    print(f"{'content':<9}{'filter':<8}{'seed':>5}{'agree':>7}{'fit gap':>9}{'auto':>8}"
          f"{'turn off':>9}{'own strap mean deg':>20}{'one-north strap mean deg':>26}{'own pelvis deg':>16}")
    rows: dict[str, list[tuple[bool, float, float, bool, float]]] = {label: [] for label in FILTERS}
    for content in CONTENTS:
        prior = leave_content_out(by_content, content)
        truth = np.concatenate(by_content[content])[:None if args.seconds is None else int(args.seconds * FPS)]
        for label, model in FILTERS.items():
            for seed in range(args.first_seed, args.first_seed + args.seeds):
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
                world = from_device_earth(readings)
                solver = _take_solver(world, FPS, NAMES, prior, 300, spins=False)
                turn = turn_north_offset_deg(world, NAMES, solver.ref, prior)
                gap = _fit_gap(solver, solutions(shared), solutions(own))
                own_deg = strap_error_deg(own.orientation.mount_wxyz, strap)
                pelvis_deg = float(own_deg[solver.ref])
                rows[label].append((agree, gap, turn, auto.north == "shared", pelvis_deg))
                print(f"{content:<9}{label:<8}{seed:>5}{'yes' if agree else 'no':>7}{gap:>+9.3f}{auto.north:>8}"
                      f"{turn:>9.0f}"
                      f"{own_deg.mean():>20.1f}"
                      f"{strap_error_deg(shared.orientation.mount_wxyz, strap).mean():>26.1f}{pelvis_deg:>16.1f}",
                      flush=True)
    for label, takes in rows.items():
        turns = [turn for _, _, turn, *_ in takes]
        gaps = [gap for agree, gap, turn, *_ in takes if not agree and turn <= HELD_TURN_NORTH_DEG]
        flips = sum(pelvis > 90.0 for *_, pelvis in takes)
        gap_text = f"{min(gaps):+.3f} .. {max(gaps):+.3f}" if gaps else "-"
        print(f"{label}: {len(takes)} takes, turn offset {min(turns):.0f}-{max(turns):.0f} deg; {len(gaps)} pass the "
              f"turns with own norths that disagree, fit gap {gap_text}; "
              f"auto took one north on {sum(one for *_, one, _ in takes)}; the own solve's pelvis strap over 90 deg "
              f"off (its twist, seen only in its tilts, turned round) on {flips}")


if __name__ == "__main__":
    main()
