"""Calibration from a recording (`courtside calibrate`): rotation error of the recovered sensor-to-segment
mountings on virtual sensors strapped 20-30° off nominal (random axis, heading included), 0.01 g noise, over
takes that stand 3 s in a relaxed N-pose then walk (shipped CMU walks joined), three seeds x two walk sets.

    python bench/bench_calibrate.py
"""
from __future__ import annotations

import itertools
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from engine.mocap import SEED000_SENSORS, standard_placements, virtual_accelerometers  # noqa: E402
from gateway.calibration.alignment import rotation_angle_deg  # noqa: E402
from gateway.calibration.recording import calibrate_recording, standard_segment_poses  # noqa: E402
from tests.engine.imu_import.formats import mounted, standing_then_walking  # noqa: E402

FPS = 100.0
NAMES = list(SEED000_SENSORS)
WALKS = [("16_11", "16_16", "16_21"), ("16_32", "16_11")]


def run(with_tpose: bool) -> tuple[np.ndarray, np.ndarray, float]:
    errors, flagged, seconds = [], [], 0.0
    for seed, walks in itertools.product((1, 2, 3), WALKS):
        motion = standing_then_walking(walks=walks, tpose_s=2.0 if with_tpose else 0.0, fps=FPS, seed=seed)
        truth = mounted(standard_placements(motion.skeleton, NAMES), seed=seed)
        rng = np.random.default_rng(seed)
        acc = virtual_accelerometers(motion, truth) + rng.normal(0.0, 0.01, (motion.n_frames, len(NAMES), 3))
        end = motion.n_frames / FPS
        t0 = time.process_time()
        record = calibrate_recording(acc, FPS, NAMES, NAMES, standard_segment_poses(NAMES, "tpose" if with_tpose else None),
                                     second_window_s=(end - 1.8, end - 0.1) if with_tpose else None,
                                     second_pose="tpose" if with_tpose else None)
        seconds += time.process_time() - t0
        errors.append([rotation_angle_deg(record.sensors[p.name].rotation @ p.rotation.T) for p in truth])
        flagged.append([bool(record.sensors[p.name].reasons) for p in truth])
    return np.array(errors), np.array(flagged), seconds / len(errors)


def main() -> None:
    for label, with_tpose in (("walking only", False), ("walking + 2 s T-pose (--second-pose)", True)):
        errors, flagged, per_take = run(with_tpose)
        print(f"{label}: {len(errors)} takes, {per_take * 1e3:.0f} ms CPU per take")
        print(f"  {'sensor':14s} {'median deg':>10s} {'max deg':>8s} {'heading flagged':>16s}")
        for k, name in enumerate(NAMES):
            print(f"  {name:14s} {np.median(errors[:, k]):10.1f} {errors[:, k].max():8.1f} "
                  f"{int(flagged[:, k].sum()):>10d} of {len(errors)}")


if __name__ == "__main__":
    main()
