"""Metrics, per-second traces and the baselines against hand computations."""
from __future__ import annotations

import numpy as np

from engine.evaluation.baselines import NearestNeighbour, dead_reckoned, mean_pose
from engine.evaluation.metrics import frame_errors, per_second
from engine.evaluation.takes import chain_clips
from engine.graph.config import GraphConfig
from engine.graph.geometry import rotate_points_y
from engine.graph.graph import build_from_clips
from engine.graph.mocap_adapter import clips_from_motions
from engine.mocap import error_joint_indices, standard_placements
from tests.engine.graph.synth import gait_clip


def test_errors_of_a_shifted_and_of_a_turned_prediction(motions):
    take = chain_clips(motions, [0, 1], [m.name for m in motions])
    shifted = take.joints_m + np.array([0.3, 0.0, -0.4])
    e = frame_errors(shifted, take.joints_m, take.skeleton)
    assert np.allclose(e.global_cm, 50.0) and np.allclose(e.position_cm, 50.0)
    assert np.allclose(e.root_relative_cm, 0.0, atol=1e-9) and np.allclose(e.heading_deg, 0.0, atol=1e-9)
    # every pose turned by 30 deg about its own root: root-relative error 0, heading error exactly 30
    turned = np.stack([rotate_points_y(p - [p[0, 0], 0, p[0, 2]], np.radians(30)) + [p[0, 0], 0, p[0, 2]]
                       for p in take.joints_m])
    e = frame_errors(turned, take.joints_m, take.skeleton)
    assert np.allclose(e.heading_deg, 30.0) and np.allclose(e.root_relative_cm, 0.0, atol=1e-9)
    assert np.allclose(e.position_cm, 0.0, atol=1e-9) and np.all(e.global_cm > 1.0)


def test_per_second_trace_has_one_value_per_started_second():
    values = np.arange(95, dtype=float)  # 3 s + 5 frames at 30 Hz
    trace = per_second(values, 30.0)
    assert len(trace) == 4
    assert np.allclose(trace, [14.5, 44.5, 74.5, 92.0])
    assert len(per_second(np.ones(90), 30.0)) == 3


def test_mean_pose_baseline_equals_a_hand_computation():
    a = gait_clip("a", 30, heading0=0.4, origin=(1.0, 2.0))
    b = gait_clip("b", 30, phase=5, heading0=-1.0, turn_rate=0.02, seed=1)
    graph = build_from_clips([a, b], GraphConfig(msv=True))  # slow-down nodes must not enter the mean
    local = []
    for c in (a, b):  # by hand: remove the root ground position, undo the heading, average
        for f in range(c.n_frames):
            p = c.positions_m[f] - [c.ground_m[f, 0], 0.0, c.ground_m[f, 1]]
            local.append(rotate_points_y(p, -c.heading_rad[f]))
    expected_local = np.mean(local, axis=0)
    ground, heading = np.array([[3.0, -2.0], [0.0, 0.5]]), np.array([np.pi / 2, 0.0])
    out = mean_pose(graph, ground, heading)
    for t in range(2):
        want = rotate_points_y(expected_local, heading[t]) + [ground[t, 0], 0.0, ground[t, 1]]
        assert np.allclose(out[t], want, atol=1e-6)


def test_nearest_neighbour_finds_a_database_window_and_dead_reckons_its_path(motions):
    cfg = GraphConfig(sensor_names=["left_forearm", "right_forearm"])
    clips = clips_from_motions(motions, standard_placements(motions[0].skeleton, cfg.sensor_names), cfg)
    graph = build_from_clips(clips, cfg)
    nn = NearestNeighbour(graph, (0, 1), window=10)
    clip = clips[2]
    start = int(np.flatnonzero(graph.node_clip == 2)[0])
    nodes = nn.match(clip.acc_g[5:35])  # clean readings of frames 5..34 of a database clip: found exactly
    assert np.array_equal(nodes, start + 5 + np.arange(30))
    ground, heading = dead_reckoned(graph, nodes, clip.ground_m[5], clip.heading_rad[5])
    assert np.allclose(ground, clip.ground_m[5:35], atol=1e-6)
    assert np.allclose(np.unwrap(heading), np.unwrap(clip.heading_rad[5:35]), atol=1e-6)
    joints, _ = nn.predict(clip.acc_g[5:35], None, None, clip.ground_m[5], clip.heading_rad[5])
    assert np.allclose(joints[:, error_joint_indices(motions[0].skeleton)],
                       clip.positions_m[5:35][:, error_joint_indices(motions[0].skeleton)], atol=1e-4)


def test_database_oracle_finds_a_database_clip_exactly_and_is_the_floor_for_a_held_out_one(motions):
    """The oracle plays, frame by frame, the database pose nearest the truth: zero root-relative error on a clip
    the database holds; on a held-out clip no database-playing baseline does better than it."""
    from engine.evaluation.baselines import database_oracle

    cfg = GraphConfig(sensor_names=["left_forearm", "right_forearm"])
    clips = clips_from_motions(motions, standard_placements(motions[0].skeleton, cfg.sensor_names), cfg)
    graph = build_from_clips(clips, cfg)
    clip = clips[2]
    joints, nodes = database_oracle(graph, clip.positions_m, motions[0].skeleton, clip.ground_m, clip.heading_rad)
    assert np.array_equal(graph.node_clip[nodes], np.full(clip.n_frames, 2))
    assert frame_errors(joints, clip.positions_m, motions[0].skeleton).root_relative_cm.max() < 1e-3
    held = graph.without_clips([2])
    joints, _ = database_oracle(held, clip.positions_m, motions[0].skeleton, clip.ground_m, clip.heading_rad)
    oracle = frame_errors(joints, clip.positions_m, motions[0].skeleton).root_relative_cm.mean()
    nn_joints, _ = NearestNeighbour(held, (0, 1), window=10).predict(clip.acc_g, clip.ground_m, clip.heading_rad,
                                                                   clip.ground_m[0], clip.heading_rad[0])
    nn = frame_errors(nn_joints, clip.positions_m, motions[0].skeleton).root_relative_cm.mean()
    assert 0.5 < oracle < nn
