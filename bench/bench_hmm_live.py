"""What the live HMM gains or loses with each channel set it may run: seed 004's acc + gyro model, the
accelerometer-only model (a stream without gyroscope), and acc + gyro + tilt (issue 18: the tilt from the device
quaternion, through `OrientationErrorModel.realistic()`).

Leave-one-out over the shipped CMU subject-16 clips (each clip held out once, the model trained on the others),
one right-foot IMU simulated on the held-out clip with the default sensor error model, reconstructed through
`engine.hmm.evaluation.hmm_leave_one_out` (foot IK on). Columns: mean joint error in the heading frame (engine.graph's
measure) and RMS in the root frame (Tautges et al.), mean over clips; the ratio column is against acc + gyro in
this run. A mean-pose baseline (the training clips' mean root-frame pose) is in the same table.

    nice -n 10 .venv/bin/python bench/bench_hmm_live.py
"""
from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from engine.hmm.config import HMMConfig  # noqa: E402
from engine.hmm.evaluation import hmm_leave_one_out  # noqa: E402
from engine.mocap import SensorErrorModel, forward_kinematics, load_clip, sample_clips  # noqa: E402
from engine.olng.metrics import root_frame  # noqa: E402


def mean_pose_rms_cm(motions, test: int) -> float:
    """RMS (root frame) of always answering the other clips' mean root-frame pose."""
    def frames(m):
        world, rot = forward_kinematics(m)
        return root_frame(world, rot[:, 0])

    mean = np.concatenate([frames(m) for i, m in enumerate(motions) if i != test]).mean(axis=0)
    truth = frames(motions[test])
    return float(100 * np.sqrt(((truth - mean) ** 2).sum(-1).mean(-1)).mean())


def main() -> int:
    motions = [load_clip(p, fps=30.0) for n, p in sample_clips().items() if n.startswith("16_")]
    tests = list(range(len(motions)))
    rows = {}
    for name, config in (("acc + gyro (seed 004)", HMMConfig()),
                         ("acc only", HMMConfig(imu_channels="acc")),
                         ("acc + gyro + tilt", HMMConfig(imu_channels="acc+gyro+tilt"))):
        scores = hmm_leave_one_out(motions, tests, ("right_foot",), error_model=SensorErrorModel(), config=config)
        rows[name] = (np.mean([s.joint_cm.mean() for s in scores]), np.mean([s.rms_root_cm.mean() for s in scores]))
    rows["mean pose (baseline)"] = (float("nan"), np.mean([mean_pose_rms_cm(motions, t) for t in tests]))
    print(f"HMM leave-one-out on {len(motions)} shipped CMU subject-16 clips, right-foot IMU, load avg "
          f"{os.getloadavg()[0]:.1f}")
    print(f"{'model':28s}{'joint cm':>10s}{'RMS root cm':>13s}{'RMS vs acc+gyro':>17s}")
    base = rows["acc + gyro (seed 004)"][1]
    for name, (joint, rms) in rows.items():
        print(f"{name:28s}{joint:10.1f}{rms:13.1f}{rms / base:17.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
