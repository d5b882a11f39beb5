"""The whole marker pipeline through the real CLIs (issue 14): courtside label (scrambled input) → courtside
fit-skeleton → BVH → courtside build-graph, on the two-player tennis serve (both players) and on a long CMU take.

The CMU test uses the first 15 s of cmu_85_12 (break dance, 4 499 frames) to stay fast; bench/bench_labeling.py
labels the full take and runs fit-skeleton on it."""
from __future__ import annotations

import json

import numpy as np

from engine.graph.cli import build_graph_main
from engine.labeling.c3d_io import write_c3d
from engine.labeling.cli import main as label_main
from engine.mocap import MarkerData, forward_kinematics, joint_roles, read_bvh, read_c3d
from engine.skeleton_fit.cli import main as fit_main


def _label(source, labelled, capsys, seed) -> float:
    assert label_main([str(source), "-o", str(labelled), "--degrade", str(seed)]) == 0
    out = capsys.readouterr().out
    return float(out.split("accuracy ")[1].split()[0])


def _fit(labelled, bvh, capsys, subject=None) -> dict[str, tuple[float, float]]:
    """Run fit-skeleton; returns {joint: (arc_deg, expected_mm)} from its report."""
    argv = [str(labelled), "-o", str(bvh)] + (["--subject", subject] if subject else [])
    assert fit_main(argv) == 0
    report = {}
    for line in capsys.readouterr().out.splitlines():
        parts = line.split()
        if len(parts) >= 7 and parts[2] in ("ball", "hinge", "static"):
            report[parts[0]] = (float(parts[5]), float(parts[6]))
    return report


def _build_graph(bvhs, out, capsys) -> dict:
    assert build_graph_main([*map(str, bvhs), "-o", str(out)]) == 0
    capsys.readouterr()
    return json.loads(out.with_suffix(".json").read_text())


def test_two_player_tennis_serve_labels_fits_both_players_and_builds_a_graph(shared_mocap, tmp_path, capsys):
    source = shared_mocap / "markers" / "ktk_kinematics_tennis_serve_2players.c3d"
    labelled = tmp_path / "labelled.c3d"
    assert _label(source, labelled, capsys, seed=5) > 0.9
    bvhs = []
    for player in ("Derrick", "Viktor"):
        bvh = tmp_path / f"{player}.bvh"
        report = _fit(labelled, bvh, capsys, player)
        assert set(report) >= {"UpperLeg_L", "LowerLeg_R", "UpperArm_R"}
        for arc, expected in report.values():  # every joint reports the arc it swept and its expected error
            assert np.isnan(arc) or 0 < arc <= 180
            assert np.isnan(expected) or expected >= 0
        motion = read_bvh(bvh)
        positions, _ = forward_kinematics(motion)
        assert np.isfinite(positions).all() and motion.rotations.shape[0] == read_c3d(source).n_frames
        height = positions[:, motion.skeleton.index("Head"), 1] - positions[:, :, 1].min(axis=1)
        assert 1.3 < np.median(height) < 2.0  # Y is up and the head sits a body height above the feet
        knee, hip = motion.skeleton.index("LowerLeg_L"), motion.skeleton.index("UpperLeg_L")
        assert 0.3 < np.median(np.linalg.norm(positions[:, knee] - positions[:, hip], axis=1)) < 0.55
        assert joint_roles(motion.skeleton)["right_wrist"] == motion.skeleton.index("Hand_R")
        bvhs.append(bvh)
    summary = _build_graph(bvhs, tmp_path / "graph.npz", capsys)
    assert summary["frames"] > 0 and summary["nodes"] > 0


def test_long_cmu_take_slice_labels_fits_and_builds_a_graph(shared_mocap, tmp_path, capsys):
    data = read_c3d(shared_mocap / "markers" / "cmu_85_12.c3d")
    frames = int(15 * data.fps)
    source = tmp_path / "cmu_85_12_15s.c3d"
    write_c3d(source, MarkerData(data.labels, data.positions_m[:frames], data.fps, data.name))
    labelled = tmp_path / "labelled.c3d"
    assert _label(source, labelled, capsys, seed=1) > 0.9
    bvh = tmp_path / "cmu.bvh"
    report = _fit(labelled, bvh, capsys)
    assert len(report) >= 10
    motion = read_bvh(bvh)
    assert motion.rotations.shape[0] == frames
    summary = _build_graph([bvh], tmp_path / "graph.npz", capsys)
    assert summary["frames"] > 0 and summary["nodes"] > 0
