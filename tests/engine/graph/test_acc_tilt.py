"""Segment tilt from accelerations for the posing (engine/graph/acc_tilt.py, issue 18 item 3), against answers
known by construction: a held pose reads gravity only, a shaken sensor reads mostly its own motion."""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.acc_tilt import TiltFromAccelerations, tilt_quaternions
from engine.graph.config import GraphConfig
from engine.graph.graph import MotionGraph
from engine.graph.orientation_pose import SegmentPosing
from engine.graph.viterbi import SearchWeights
from engine.mocap import Motion, forward_kinematics, joint_roles, standard_placements, virtual_accelerometers
from engine.mocap import quaternions as quat
from engine.mocap.orientation import twist_yaw

UP = np.array([0.0, 1.0, 0.0])


def test_tilt_quaternions_carry_the_reading_onto_up_with_no_twist():
    rng = np.random.default_rng(2)
    up_sensor = rng.normal(size=(40, 3))
    q = tilt_quaternions(up_sensor)
    assert np.allclose(quat.rotate(q, up_sensor / np.linalg.norm(up_sensor, axis=1, keepdims=True)), UP, atol=1e-9)
    assert np.allclose(twist_yaw(q), 0.0, atol=1e-9)


def test_a_still_sensor_gets_its_whole_share_and_a_shaken_one_almost_none():
    fps = 30.0
    still, shaken = TiltFromAccelerations(fps), TiltFromAccelerations(fps)
    gravity = np.array([[0.3, 0.9, 0.1]])
    t = np.arange(90) / fps
    for k in range(90):
        q_still, share_still = still.push(gravity)
        wobble = np.array([[np.sin(2 * np.pi * 2.0 * t[k]), 0.0, np.cos(2 * np.pi * 2.0 * t[k])]])
        _, share_shaken = shaken.push(gravity + wobble)  # 1 g of swing at 2 Hz: a limb in a stride
    assert share_still[0] > 0.999 and share_shaken[0] < 0.05
    assert np.allclose(quat.rotate(q_still, gravity / np.linalg.norm(gravity)), UP, atol=1e-9)


def test_a_missing_reading_keeps_the_estimate_and_takes_no_share():
    tilt = TiltFromAccelerations(30.0)
    reading = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    for _ in range(30):
        q, _ = tilt.push(reading)
    q_gap, share = tilt.push(np.array([[0.0, 1.0, 0.0], [np.nan, np.nan, np.nan]]))
    assert share[1] == 0.0 and share[0] > 0.99 and np.allclose(q_gap, q)


@pytest.fixture(scope="module")
def graph(sample_motions):
    return MotionGraph.build(sample_motions, standard_placements(sample_motions[0].skeleton), GraphConfig())


def test_a_held_pose_gives_the_worn_bones_their_elevation_from_accelerations_alone(graph, sample_motions):
    """A frame of clip 0 held still for 2 s reads gravity only: posing another clip's nodes by the accelerations
    gives each worn bone (elbow -> wrist, knee -> ankle) the held pose's elevation."""
    source = sample_motions[0]
    frame = 25
    held = Motion(source.skeleton, source.fps, np.repeat(source.root_positions_m[frame:frame + 1], 60, axis=0),
                  np.repeat(source.rotations[frame:frame + 1], 60, axis=0))
    acc = virtual_accelerometers(held, standard_placements(held.skeleton))
    assert np.allclose(np.linalg.norm(acc, axis=-1), 1.0, atol=1e-6)  # gravity only
    posing = SegmentPosing.for_search(graph, tuple(range(6)), SearchWeights())
    world, share = posing.over_take(acc, None)
    assert share[-1].min() > 0.999
    roles = joint_roles(graph.skeleton)
    bones = [(roles[f"{s}_{a}"], roles[f"{s}_{b}"]) for s in ("left", "right")
             for a, b in (("elbow", "wrist"), ("knee", "ankle"))]

    def elevation_deg(pts):
        d = np.stack([pts[..., b, :] - pts[..., a, :] for a, b in bones], axis=-2)
        return np.degrees(np.arcsin(d[..., 1] / np.linalg.norm(d, axis=-1)))

    nodes = np.flatnonzero(graph.node_clip == 2)[:10]
    posed = posing.poser.pose(nodes, world[-1][None], share[-1][None], use_yaw=False)
    truth = forward_kinematics(held)[0][-1]
    assert np.abs(elevation_deg(posed) - elevation_deg(truth)).max() < 0.5
    assert np.abs(elevation_deg(graph.node_positions_m[nodes].astype(float)) - elevation_deg(truth)).max() > 5.0
