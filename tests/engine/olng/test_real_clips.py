"""OLNG leave-one-out on the real CMU subject-16 clips shipped in engine/data (spec A5 offline trends)."""
from __future__ import annotations

import numpy as np
import pytest

from engine.mocap import SEED003_SENSORS, resample, standard_placements, virtual_accelerometers
from engine.olng.config import EnergyConfig, NeighbourhoodGraphConfig, KnowledgeBaseConfig, OLNGConfig
from engine.olng.evaluation import Variant, olng_leave_one_out, mean_pose_baseline
from engine.olng.metrics import summarise

GRAPH = NeighbourhoodGraphConfig(k_neighbours=512, i_best=32)


def test_leave_one_out_beats_baselines_on_real_walks(native_motions):
    """Held-out walk 16_32: the kernel prior beats the Mahalanobis prior and the database mean pose, and time
    warping beats the linear search."""
    tests = [5]
    kb = KnowledgeBaseConfig(mirror=True)
    variants = [Variant("olng", OLNGConfig(graph=GRAPH)),
                Variant("mahalanobis", OLNGConfig(graph=GRAPH, energy=EnergyConfig(kernel="mahalanobis"))),
                Variant("no-warp", OLNGConfig(graph=NeighbourhoodGraphConfig(k_neighbours=512, i_best=32, max_column_step=1, max_warp=1)))]
    scores = {k: summarise(v)["rms_root_cm"] for k, v in olng_leave_one_out(native_motions, tests, variants, kb).items()}
    mean_pose = summarise(mean_pose_baseline(native_motions, tests, kb))["rms_root_cm"]
    assert scores["olng"] < 0.6 * mean_pose
    assert scores["olng"] < 0.7 * scores["mahalanobis"]
    assert scores["olng"] < scores["no-warp"]


def test_cli_reconstructs_a_take_to_bvh_and_rejects_missing_sensors(tmp_path, native_motions):
    from engine.mocap import read_bvh
    from engine.reconstruct_cli import main

    take = resample(native_motions[5], 50.0)
    acc = virtual_accelerometers(take, standard_placements(take.skeleton, SEED003_SENSORS))
    path = tmp_path / "take.npz"
    np.savez(path, acc_g=acc, fps=50.0, sensor_names=np.array(SEED003_SENSORS))
    out = tmp_path / "out.bvh"
    assert main(["--method", "olng", "--input", str(path), "-o", str(out), "--sample", "--k", "256", "--i-best", "16"]) == 0
    result = read_bvh(out)
    assert result.n_frames == pytest.approx(take.duration_s * 25, abs=2)
    assert result.skeleton.n_joints == native_motions[0].skeleton.n_joints
    np.savez(tmp_path / "two.npz", acc_g=acc[:, :2], fps=50.0, sensor_names=np.array(SEED003_SENSORS[:2]))
    assert main(["--method", "olng", "--input", str(tmp_path / "two.npz"), "-o", str(out), "--sample"]) == 2


def test_evaluate_prints_the_orientation_rows(capsys):
    """`reconstruct --evaluate --orientations` adds the OLNG rows that search on orientation (+ angular rate),
    each a finite error in the same table as the accelerometer row and the mean pose."""
    from engine.reconstruct_cli import main

    assert main(["--evaluate", "--sample", "--test-clips", "1", "--methods", "olng", "--orientations",
                 "--k", "128", "--i-best", "8"]) == 0
    rows = {line[:28].strip(): line[28:].split() for line in capsys.readouterr().out.splitlines()}
    for name in ("olng (4 acc)", "olng (4 acc + orientation)", "olng (4 acc + ori + gyro)", "database mean pose"):
        assert np.isfinite(float(rows[name][0])), name
