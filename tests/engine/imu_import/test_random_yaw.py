"""Issue 18's import criterion: a CSV whose quaternions come from devices with no shared north (a random yaw per
sensor) synthesises as well as the same take with aligned yaws -- the motion graph learns each sensor's yaw
offset from its own decisions (engine/graph/orientation_term.py) and the worn segments are posed by their tilt
(engine/graph/orientation_pose.py), which needs no north."""
from __future__ import annotations

import numpy as np
import pytest

from engine.evaluation.metrics import frame_errors
from engine.graph.config import GraphConfig
from engine.graph.graph import MotionGraph
from engine.graph.orientation_pose import SegmentPosing
from engine.graph.decided import decided_poses
from engine.graph.search import ViterbiSearch
from engine.graph.viterbi import Observations, SearchWeights
from engine.mocap import (SEED000_SENSORS, forward_kinematics, load_database, sample_clips, standard_placements,
                          virtual_accelerometers)
from engine.mocap.orientation import to_device_earth, virtual_orientations
from gateway.cli import main as courtside

FPS = 30.0
HELD_OUT = "16_11"  # a walk; the graph holds the other shipped subject-16 clips
# the heading part on (the tilt part alone needs no north at all: equal by construction)
WEIGHTS = SearchWeights(1.0, 0.0, 0.0, forgetting=0.9, decision_frames=6, blend_paths=8, orientation=1.0,
                        orientation_heading=0.5)


@pytest.fixture(scope="module")
def setup():
    clips = sample_clips()
    motions = load_database([p for n, p in sorted(clips.items()) if n.startswith("16_") and n != HELD_OUT], fps=FPS)
    placements = standard_placements(motions[0].skeleton)
    graph = MotionGraph.build(motions, placements, GraphConfig(msv=True))
    take = load_database([clips[HELD_OUT]], fps=FPS)[0]
    return graph, take


def _write_csv(path, acc_g: np.ndarray, quat_wxyz: np.ndarray) -> list[str]:
    """One row per sample: t, then per sensor ax ay az (g) and qw qx qy qz; returns the import-imu arguments."""
    n, s, _ = acc_g.shape
    cols, args = ["t"], []
    for k, name in enumerate(SEED000_SENSORS[:s]):
        a, q = [f"a{c}{k}" for c in "xyz"], [f"q{c}{k}" for c in "wxyz"]
        cols += a + q
        args += ["--sensor", f"{name}={','.join(a)}", "--quat", f"{name}={','.join(q)}"]
    data = np.concatenate([np.arange(n)[:, None] / FPS, np.concatenate([acc_g, quat_wxyz], axis=2).reshape(n, -1)],
                          axis=1)
    np.savetxt(path, data, delimiter=",", header=",".join(cols), comments="", fmt="%.7f")
    return args


def _synthesise(graph: MotionGraph, take_npz) -> np.ndarray:
    """World joints (T, J, 3) the batch search gives for an imported take (no camera: root-relative is scored)."""
    with np.load(take_npz, allow_pickle=False) as data:
        names = [str(n) for n in data["sensor_names"]]
        order = [names.index(n) for n in graph.config.sensor_names]
        acc, quats = data["acc_g"][:, order], data["quat_wxyz"][:, order]
    res = ViterbiSearch(graph, WEIGHTS).run(Observations(acc, quat_wxyz=quats))
    posing = SegmentPosing.for_search(graph, tuple(range(len(order))), WEIGHTS)  # tilt: no calibration
    return posing.decide(res.blend_nodes, res.ground_m, res.heading_rad,
                         *posing.over_take(acc, quats)).joint_positions_m


def test_random_per_sensor_yaws_synthesise_as_well_as_aligned_ones(setup, tmp_path):
    graph, take = setup
    placements = standard_placements(take.skeleton)
    acc = virtual_accelerometers(take, placements)
    q_world = virtual_orientations(take, placements)
    yaws = np.random.default_rng(18).uniform(-np.pi, np.pi, len(placements))
    truth, _ = forward_kinematics(take)
    errors = {}
    for name, yaw in (("aligned", 0.0), ("random", yaws)):
        csv = tmp_path / f"{name}.csv"
        args = _write_csv(csv, acc, to_device_earth(q_world, yaw))
        out = tmp_path / f"{name}.npz"
        assert courtside(["import-imu", str(csv), "--format", "csv", "--time", "t", "--quat-order", "wxyz",
                          *args, "-o", str(out)]) == 0
        joints = _synthesise(graph, out)  # the import's grid spans the samples every sensor covers: one fewer
        errors[name] = frame_errors(joints, truth[:len(joints)], take.skeleton).root_relative_cm.mean()
    assert abs(errors["random"] - errors["aligned"]) <= 0.3, errors
    acc_only = replace_weights(0.0)
    res = ViterbiSearch(graph, acc_only).run(Observations(acc))
    baseline = frame_errors(decided_poses(graph, res.blend_nodes, res.ground_m, res.heading_rad).joint_positions_m,
                            truth, take.skeleton).root_relative_cm.mean()
    assert errors["random"] < baseline  # and the orientations help (measured 1.38 vs 2.96 cm)
    print(f"root-relative error: aligned {errors['aligned']:.2f} cm, random yaws {errors['random']:.2f} cm, "
          f"accelerations only {baseline:.2f} cm")


def replace_weights(orientation: float) -> SearchWeights:
    from dataclasses import replace

    return replace(WEIGHTS, orientation=orientation)
