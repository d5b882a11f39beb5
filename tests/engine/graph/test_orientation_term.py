"""The motion graph's orientation term (engine/graph/orientation_term.py, issue 18) on the shipped CMU clips,
against answers known by construction: the database's own orientations, turned by known per-sensor yaws."""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.config import GraphConfig
from engine.graph.graph import MotionGraph
from engine.graph.parts import NODE_ORIGINAL
from engine.graph.online import FixedLagSynthesizer
from engine.graph.orientation_term import OrientationTerm, features, roll_axis_weights, twist_yaw
from engine.graph.search import ViterbiSearch
from engine.graph.viterbi import Observations, SearchWeights
from engine.mocap import quaternions as quat
from engine.mocap import SEED000_SENSORS, standard_placements, virtual_accelerometers
from engine.mocap.orientation import to_device_earth, virtual_orientations, yaw_about_up

WEIGHTS = SearchWeights(1.0, 0.0, 0.0, forgetting=0.9, decision_frames=6, blend_paths=4, orientation=1.0,
                        orientation_heading=1.0)
YAWS = np.array([2.0, -1.3, 0.4, 3.0, -2.5, 1.1])  # per-sensor device yaw offsets (rad), the pelvis's is -2.5


@pytest.fixture(scope="module")
def graph(sample_motions):
    return MotionGraph.build(sample_motions, standard_placements(sample_motions[0].skeleton), GraphConfig())


@pytest.fixture(scope="module")
def take(graph, sample_motions):
    """Database clip 0 as a device would report it: accelerations, and orientations with per-sensor yaws."""
    motion = sample_motions[0]
    placements = standard_placements(motion.skeleton)
    q_world = virtual_orientations(motion, placements)
    return (virtual_accelerometers(motion, placements), q_world, to_device_earth(q_world, YAWS))


def test_twist_yaw_takes_up_a_turn_of_the_frame_exactly():
    rng = np.random.default_rng(0)
    q = quat.normalize(rng.normal(size=(50, 4)))
    turn = rng.uniform(-np.pi, np.pi, 50)
    moved = twist_yaw(quat.multiply(yaw_about_up(turn), q)) - twist_yaw(q)
    assert np.allclose(np.angle(np.exp(1j * (moved - turn))), 0.0, atol=1e-9)


def test_features_need_no_north(take):
    """Tilt is yaw-free; with each sensor's offset relative to the pelvis removed, the heading part is too."""
    _, q_world, _ = take
    turned = quat.multiply(yaw_about_up(YAWS), q_world)
    assert np.allclose(features(turned, None, None), features(q_world, None, None), atol=1e-9)
    relative = YAWS - YAWS[4]
    assert np.allclose(features(turned, 4, relative), features(q_world, 4, np.zeros(6)), atol=1e-9)
    assert not np.allclose(features(turned, 4, np.zeros(6)), features(q_world, 4, np.zeros(6)), atol=0.1)


def test_database_rows_are_the_features_of_the_clip_poses(graph, take):
    _, q_world, _ = take
    term = OrientationTerm(graph, list(range(6)), 1.0, 1.0)
    nodes = np.flatnonzero((graph.node_clip == 0) & (graph.node_kind == NODE_ORIGINAL))
    rows = term.meta_rows_t[:, graph.node_arrival[nodes]].T
    want = features(q_world[graph.node_frame[nodes].astype(int)], 4, np.zeros(6)).reshape(len(nodes), -1)
    assert np.allclose(rows, want * term.scale, atol=1e-5)
    assert term.meta_rows_t.shape[0] == 9 * 6  # tilt (3 per sensor) + heading (6 per sensor)
    assert OrientationTerm(graph, list(range(6)), 1.0, 0.0).meta_rows_t.shape[0] == 3 * 6  # tilt alone


def test_yaw_offsets_are_learnt_from_the_decided_samples(graph, take):
    """Decoding a database clip from orientations with unknown per-sensor yaws, the search's decisions give each
    sensor's yaw relative to the pelvis's: the offsets the device frames were turned by."""
    acc, _, q_device = take
    syn = FixedLagSynthesizer(graph, 0.5, WEIGHTS, confidence_reference=1.0)
    for t in range(len(acc)):
        syn.push(acc[t], quat_wxyz=q_device[t])
    encoder = syn.lattice._encoder
    learnt = np.angle(encoder._sum)
    want = YAWS - YAWS[4]
    assert np.degrees(np.abs(np.angle(np.exp(1j * (learnt - want))))).max() < 1.0


@pytest.mark.parametrize("kernel", ["numba", "numpy"])
def test_batch_equals_fixed_lag_with_orientations(graph, take, kernel):
    acc, _, q_device = take
    rng = np.random.default_rng(1)
    acc = acc + rng.normal(0.0, 0.2, acc.shape)
    batch = ViterbiSearch(graph, WEIGHTS, kernel=kernel).run(Observations(acc, quat_wxyz=q_device))
    syn = FixedLagSynthesizer(graph, 2.0, WEIGHTS, kernel=kernel, confidence_reference=1.0)
    out = []
    for t in range(len(acc)):
        out += syn.push(acc[t], quat_wxyz=q_device[t])
    out += syn.flush()
    assert np.array_equal([p.node for p in out], batch.nodes)
    assert np.array_equal(np.stack([p.blend_nodes for p in out]), batch.blend_nodes)


def test_without_orientations_nothing_changes(graph, take, sample_graph):
    """The term on but no quaternions in the take, or a graph without joint rotations: the acc-only search."""
    acc, _, q_device = take
    acc_only = replace_orientation(WEIGHTS, 0.0)
    want = ViterbiSearch(graph, acc_only).run(Observations(acc))
    got = ViterbiSearch(graph, WEIGHTS).run(Observations(acc))
    assert np.array_equal(got.nodes, want.nodes) and got.cost == want.cost
    assert sample_graph.skeleton is None  # built from clip arrays: no skeleton to place the sensors on
    n = min(len(acc), 60)
    want = ViterbiSearch(sample_graph, acc_only).run(Observations(acc[:n]))
    got = ViterbiSearch(sample_graph, WEIGHTS).run(Observations(acc[:n], quat_wxyz=q_device[:n]))
    assert np.array_equal(got.nodes, want.nodes)


def test_a_missing_orientation_sample_uses_the_accelerations_alone(graph, take):
    acc, _, q_device = take
    q = q_device.copy()
    q[10:20, 2] = np.nan  # one sensor's filter dropped out for a third of a second
    batch = ViterbiSearch(graph, WEIGHTS).run(Observations(acc, quat_wxyz=q))
    assert len(batch.nodes) == len(acc)
    syn = FixedLagSynthesizer(graph, 2.0, WEIGHTS, confidence_reference=1.0)
    out = []
    for t in range(len(acc)):
        out += syn.push(acc[t], quat_wxyz=q[t])
    out += syn.flush()
    assert np.array_equal([p.node for p in out], batch.nodes)


def replace_orientation(weights: SearchWeights, value: float) -> SearchWeights:
    from dataclasses import replace

    return replace(weights, orientation=value)


def test_a_calibration_gives_the_heading_part_from_the_first_sample(graph, take):
    """Known yaw offsets (the N-pose calibration's): the readings are turned into the world and the heading part
    is on from sample 0 with nothing to learn -- the features of the true orientations."""
    from engine.mocap.orientation_calibration import OrientationCalibration

    _, q_world, q_device = take
    calibration = OrientationCalibration(YAWS, np.tile([1.0, 0.0, 0.0, 0.0], (6, 1)))
    term = OrientationTerm(graph, list(range(6)), 1.0, 0.0, calibration=calibration, calibrated_heading_share=0.5,
                           roll_share=0.25)
    assert term.reference == 4 and term.heading_share == 0.5
    encoder = term.encoder()
    got = np.stack([encoder.push(q) for q in q_device[:5]])
    want = features(q_world[:5], 4, np.zeros(6), 0.5, roll_axis_weights(list(graph.config.sensor_names), 0.25))
    assert np.allclose(got, want * term.scale, atol=1e-9)


def test_a_forearm_s_roll_about_its_bone_weighs_its_share_and_where_the_bone_points_all(take):
    """Calibrated orientations are the nominal sensor frames (a forearm's X along its bone): rolled about X, a
    forearm's features move by exactly `roll_share` of what they move at 1 (0: not at all), while a turn of the
    bone itself moves them at any share, and the other sensors are untouched."""
    _, q_world, _ = take
    names = list(SEED000_SENSORS)
    rolled = q_world.copy()
    rolled[:, 0] = quat.multiply(q_world[:, 0], quat.from_rotvec(np.array([0.7, 0.0, 0.0])))  # about the bone
    swung = q_world.copy()
    swung[:, 0] = quat.multiply(q_world[:, 0], quat.from_rotvec(np.array([0.0, 0.0, 0.7])))  # the bone turns

    def moved(q: np.ndarray, share: float) -> np.ndarray:
        w = roll_axis_weights(names, share)
        return features(q, 4, np.zeros(6), 0.5, w) - features(q_world, 4, np.zeros(6), 0.5, w)

    full = moved(rolled, 1.0)
    assert np.abs(full).max() > 0.3
    assert np.allclose(moved(rolled, 0.25), 0.25 * full, atol=1e-12)
    assert np.allclose(moved(rolled, 0.0), 0.0, atol=1e-12)
    assert np.abs(moved(swung, 0.0)).max() > 0.3
    other = np.ones(18, bool)
    other[[0, 6, 7]] = False  # the left forearm's tilt row and its two heading rows
    assert np.allclose(moved(rolled, 1.0)[:, other], 0.0, atol=1e-12)
