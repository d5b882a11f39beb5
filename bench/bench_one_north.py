"""One north or one each (`calibrate_take(north=...)`, docs/imu-import.md "One north"): the numbers behind
`ONE_NORTH_DEG` and the cost of the shared solve, on the shipped CMU subject-16 walks and runs (60 Hz, six
virtual orientation sensors strapped uniformly over all rotations, a 40-degree A-pose held 2 s first; the
database holds the take's motion, so this is the method's known answer, not its accuracy on unseen motion).

Per take and filter: how far the sensors' own solved norths lie from their circular mean (the agreement test),
what `auto` decides (the turn test `HELD_TURN_NORTH_DEG`, then the agreement or the fit test
`HELD_ONE_NORTH_FIT`), the worst strap error of the own and the shared solve, and their seconds (the ratio,
shared / own, in the same process). Then how often uniform random norths pass the agreement test.

    python bench/bench_one_north.py [--seeds 6]
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
from engine.mocap.orientation import OrientationErrorModel, virtual_orientations  # noqa: E402
from engine.mocap.orientation_calibration import pose_sensor_orientations  # noqa: E402
from engine.mocap.take_calibration import MotionPrior, PoseSpec, _norths_agree, calibrate_take  # noqa: E402

FPS = 60.0
NAMES = list(M.SEED000_SENSORS)
ARM_DEG = 40.0
FILTERS = {"one north": OrientationErrorModel(yaw_offset=True, north_spread_deg=0.0),
           "one north, 4 deg sd": OrientationErrorModel(yaw_offset=True, north_spread_deg=4.0),
           "a north each": OrientationErrorModel(yaw_offset=True)}


def strap_error_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per sensor, the angle between two strap quaternions (degrees)."""
    return np.degrees(2 * np.arccos(np.minimum(1.0, np.abs(np.sum(a * b, axis=-1)))))


def strapped_take(skeleton, truth: np.ndarray, model: OrientationErrorModel, seed: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The readings (the A-pose held 2 s, then the motion; every sensor strapped by a uniform random rotation,
    read through `model`) and the straps."""
    rng = np.random.default_rng(seed)
    strap = quat.normalize(rng.normal(size=(len(NAMES), 4)))
    held = pose_sensor_orientations(skeleton, NAMES, "apose", arm_deg=ARM_DEG)
    q = np.concatenate([np.repeat(held[None], int(2 * FPS), 0), truth])
    return model.apply(quat.multiply(q, strap[None]), FPS, rng), strap


def timed_calibration(readings, skeleton, prior, north: str):
    start = time.perf_counter()
    solved = calibrate_take(readings, FPS, NAMES, skeleton, PoseSpec("apose"), prior, north=north)
    return solved, time.perf_counter() - start


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=6, help="takes per filter (strap and north draws)")
    args = p.parse_args()
    clips = [M.resample(M.load_clip(M.sample_clips()[c]), FPS) for c in ("16_11", "16_16", "16_35", "16_45")]
    truth = np.concatenate([virtual_orientations(m, M.standard_placements(m.skeleton, NAMES)) for m in clips])
    skeleton, prior = clips[0].skeleton, MotionPrior(truth, tuple(NAMES))
    print(f"{'filter':<22}{'seed':>5}{'own norths max off':>20}{'auto':>8}{'own strap max':>15}"
          f"{'shared strap max':>18}{'own s':>8}{'shared s':>10}")
    own_s = shared_s = 0.0
    for label, model in FILTERS.items():
        for seed in range(1, args.seeds + 1):
            readings, strap = strapped_take(skeleton, truth, model, seed)
            own, t_own = timed_calibration(readings, skeleton, prior, "own")
            shared, t_shared = timed_calibration(readings, skeleton, prior, "shared")
            z = np.exp(1j * own.orientation.yaw_rad)
            off = np.degrees(np.abs(np.angle(z * np.conj(z.mean())))).max()
            auto = timed_calibration(readings, skeleton, prior, "auto")[0].north
            own_s, shared_s = own_s + t_own, shared_s + t_shared
            print(f"{label:<22}{seed:>5}{off:>20.1f}{auto:>8}"
                  f"{strap_error_deg(own.orientation.mount_wxyz, strap).max():>15.1f}"
                  f"{strap_error_deg(shared.orientation.mount_wxyz, strap).max():>18.1f}{t_own:>8.1f}{t_shared:>10.1f}")
    print(f"shared solve / own solve, seconds: {shared_s / own_s:.2f} ({shared_s:.0f} s / {own_s:.0f} s)")
    rng = np.random.default_rng(0)
    for n in (4, 5, 6):
        rate = np.mean([_norths_agree(list(y)) for y in rng.uniform(0, 2 * np.pi, (20000, n))])
        print(f"uniform random norths, {n} sensors: {100 * rate:.1f} % pass the agreement test")


if __name__ == "__main__":
    main()
