"""Calibration from a recording (`courtside calibrate`): rotation error of the recovered sensor-to-segment
mountings on virtual sensors strapped 20-30° off nominal (random axis, heading included), 0.01 g noise, over
takes that stand 3 s in a relaxed N-pose, move into walking within 1 s and walk: shipped CMU subject-16 walks
(three seeds x two walk sets; the bands were chosen on these) and, held out, the seven walking styles of
Bandai-Namco dataset 2 (two clips each, other actors) when the shared mocap set is present.

    python bench/bench_calibrate.py [--shared ../shared/mocap]
"""
from __future__ import annotations

import argparse
import glob
import itertools
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from engine.mocap import (SEED000_SENSORS, load_clip, rebase_to_tpose, standard_placements,  # noqa: E402
                          virtual_accelerometers)
from gateway.calibration.alignment import rotation_angle_deg  # noqa: E402
from gateway.calibration.recording import calibrate_recording, standard_segment_poses  # noqa: E402
from bench.support.imu_formats import mounted, standing_then_walking  # noqa: E402

FPS = 100.0
NAMES = list(SEED000_SENSORS)
WALKS = [("16_11", "16_16", "16_21"), ("16_32", "16_11")]


def run(takes: list[tuple], with_poses: bool, skeleton=None) -> tuple[np.ndarray, np.ndarray, float]:
    """``takes``: (walks, seed) per take; walks are shipped clip names or Motions of ``skeleton``. With
    ``with_poses`` the take ends with a 2 s T-pose, a 2 s forward bow and a 2 s long sit, each reached within 1 s."""
    errors, flagged, seconds = [], [], 0.0
    poses = standard_segment_poses(NAMES, ("tpose", "bow", "sit") if with_poses else (), skeleton)
    hold = 2.0 if with_poses else 0.0
    for walks, seed in takes:
        motion = standing_then_walking(walks=walks, tpose_s=hold, bow_s=hold, sit_s=hold, fps=FPS, seed=seed)
        truth = mounted(standard_placements(motion.skeleton, NAMES), seed=seed)
        rng = np.random.default_rng(seed)
        acc = virtual_accelerometers(motion, truth) + rng.normal(0.0, 0.01, (motion.n_frames, len(NAMES), 3))
        end = motion.n_frames / FPS
        windows = {"tpose": (end - 7.8, end - 6.1), "bow": (end - 4.8, end - 3.1), "sit": (end - 1.8, end - 0.1)} \
            if with_poses else None
        t0 = time.process_time()
        record = calibrate_recording(acc, FPS, NAMES, NAMES, poses, second_windows=windows)
        seconds += time.process_time() - t0
        errors.append([rotation_angle_deg(record.sensors[p.name].rotation @ p.rotation.T) for p in truth])
        flagged.append([bool(record.sensors[p.name].reasons) for p in truth])
    return np.array(errors), np.array(flagged), seconds / len(errors)


def table(label: str, takes: list[tuple], skeleton=None) -> None:
    for variant, with_poses in (("walking only", False),
                                ("walking + 2 s T-pose + 2 s bow + 2 s long sit (--second-pose)", True)):
        errors, flagged, per_take = run(takes, with_poses, skeleton)
        print(f"{label}, {variant}: {len(errors)} takes, {per_take * 1e3:.0f} ms CPU per take")
        print(f"  {'sensor':14s} {'median deg':>10s} {'max deg':>8s} {'heading flagged':>16s}")
        for k, name in enumerate(NAMES):
            print(f"  {name:14s} {np.median(errors[:, k]):10.1f} {errors[:, k].max():8.1f} "
                  f"{int(flagged[:, k].sum()):>10d} of {len(errors)}")


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--shared", default=str(Path(__file__).resolve().parents[2] / "shared" / "mocap"))
    args = p.parse_args()
    table("CMU subject 16", [(walks, seed) for seed, walks in itertools.product((1, 2, 3), WALKS)])
    files = sorted(glob.glob(str(Path(args.shared) / "bandai-namco-2" / "data" / "dataset-2_walk_*_00[12].bvh")))
    if files:
        clips = [rebase_to_tpose(load_clip(f)) for f in files]
        takes = [((clips[i], clips[i + 1]), seed) for seed, i in enumerate(range(0, len(clips) - 1, 2), start=1)]
        table("Bandai dataset 2, 7 walking styles (held out)", takes, clips[0].skeleton)
    else:
        print(f"(no Bandai-Namco dataset 2 under {args.shared}: held-out table skipped)")


if __name__ == "__main__":
    main()
