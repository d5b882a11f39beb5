"""The unworn upper arm / thigh looked up from the worn forearm / shin (engine/graph/limb_prior.py, issue 18),
against answers known by construction: a lookup of a database pose's own forearm gives that pose's upper arm,
posing one node onto another node's sensors (k = 1) rebuilds the other node's arm about the shoulder and leg
about the hip, the tilt-only lookup does not see any sensor's yaw, and the shortest rotation between two
directions is exact."""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.config import GraphConfig
from engine.graph.graph import MotionGraph
from engine.graph.limb_prior import LimbPrior, rotation_between
from engine.graph.orientation_pose import SegmentPoser
from engine.graph.orientation_term import node_sensor_orientations
from engine.mocap import joint_roles
from engine.mocap import quaternions as quat
from engine.mocap import standard_placements
from engine.mocap.orientation import yaw_about_up

RIGHT_FOREARM, PELVIS, CHEST = 1, 4, 5  # standard sensor order: forearms, shins, lower back, chest
YAWS = np.array([2.0, -1.3, 0.4, 3.0, -2.5, 1.1])  # per-sensor yaws (rad) a tilt-only lookup must not see


@pytest.fixture(scope="module")
def graph(sample_motions):
    return MotionGraph.build(sample_motions, standard_placements(sample_motions[0].skeleton), GraphConfig())


ARM = (CHEST, ("right_shoulder", "right_elbow", "right_wrist", "right_hand"))
LEG = (PELVIS, ("right_hip", "right_knee", "right_ankle", "right_toe"))


def _limb_in_anchor_frame(graph, nodes, pts, limb):
    """(n, 3, 3) the limb's three bones (upper arm / thigh first, then forearm / shin, hand / foot) in its anchor
    sensor's frame (chest / pelvis) of each node's *played* orientation (the posing keeps the anchor where it
    was)."""
    anchor, chain_roles = limb
    roles = joint_roles(graph.skeleton)
    chain = [roles[r] for r in chain_roles]
    bones = np.stack([pts[:, b] - pts[:, a] for a, b in zip(chain, chain[1:])], axis=1)
    return quat.rotate(quat.conjugate(node_sensor_orientations(graph)[nodes, anchor])[:, None], bones)


def test_a_database_pose_s_own_forearm_looks_up_its_own_upper_arm(graph):
    roles = joint_roles(graph.skeleton)
    q = node_sensor_orientations(graph)
    pts = graph.node_positions_m.astype(float)
    prior = LimbPrior(q, pts, np.array([RIGHT_FOREARM]), np.array([CHEST]), np.array([roles["right_shoulder"]]),
                      np.array([roles["right_elbow"]]), k=1)
    nodes = np.arange(0, graph.n_nodes, 29)
    got = prior.directions(q[nodes, CHEST][:, None], q[nodes, RIGHT_FOREARM][:, None], np.array([0]), False)[:, 0]
    limb = pts[nodes, roles["right_elbow"]] - pts[nodes, roles["right_shoulder"]]
    want = quat.rotate(quat.conjugate(q[nodes, CHEST]), limb / np.linalg.norm(limb, axis=-1, keepdims=True))
    assert np.degrees(np.arccos(np.clip(np.sum(got * want, axis=-1), -1, 1))).max() < 0.01
    everyone = LimbPrior(q, pts, np.array([RIGHT_FOREARM]), np.array([CHEST]), np.array([roles["right_shoulder"]]),
                         np.array([roles["right_elbow"]]), k=graph.n_nodes)
    mean = everyone.directions(q[:1, CHEST][:, None], q[:1, RIGHT_FOREARM][:, None], np.array([0]), False)[0, 0]
    all_dirs = quat.rotate(quat.conjugate(q[:, CHEST]), (pts[:, roles["right_elbow"]] - pts[:, roles["right_shoulder"]]))
    all_dirs /= np.linalg.norm(all_dirs, axis=-1, keepdims=True)
    assert np.allclose(mean, all_dirs.mean(0) / np.linalg.norm(all_dirs.mean(0)), atol=1e-9)


@pytest.mark.parametrize("limb", [ARM, LEG], ids=["arm", "leg"])
def test_posing_a_node_onto_another_s_sensors_rebuilds_that_node_s_limb(graph, limb):
    """k = 1, relative (calibrated) lookup: node A played, node B's orientations measured. The anchor (chest /
    pelvis) turns onto B's, the upper arm / thigh onto B's (looked up: B is its own nearest forearm / shin), the
    forearm / shin onto B's, so in the anchor's frame the limb's two upper bones are B's -- where the hinge
    share alone keeps A's elbow / knee angle."""
    q = node_sensor_orientations(graph)
    a_nodes = np.arange(5, graph.n_nodes // 2, 41)
    b_nodes = a_nodes + graph.n_nodes // 2
    with_prior = SegmentPoser(graph, list(range(6)), hinge_share=0.5, limb_prior_k=1, prior_misfit_rad=1e-9)
    assert list(with_prior.prior_limb) == [0, 1, 2, 3, -1, -1]  # forearms and shins
    posed = with_prior.pose(a_nodes, q[b_nodes], use_yaw=True)
    # posing keeps the played pose's hips heading, so compare in the posed anchor's frame: B's anchor
    # orientation turned by that heading keep; the bones' directions relative to the anchor do not depend on it
    anchor = limb[0]
    want = _limb_in_anchor_frame(graph, b_nodes, graph.node_positions_m[b_nodes].astype(float), limb)
    got = quat.rotate(_heading_turn(graph, a_nodes, b_nodes, posed, anchor)[:, None],
                      _limb_in_anchor_frame(graph, b_nodes, posed, limb))
    upper_two_bones = slice(0, 2)
    assert np.abs(got[:, upper_two_bones] - want[:, upper_two_bones]).max() < 1e-4
    hinge_only = SegmentPoser(graph, list(range(6)), hinge_share=0.5).pose(a_nodes, q[b_nodes], use_yaw=True)
    hinged = quat.rotate(_heading_turn(graph, a_nodes, b_nodes, hinge_only, anchor)[:, None],
                         _limb_in_anchor_frame(graph, b_nodes, hinge_only, limb))
    assert np.abs(hinged[:, 0] - want[:, 0]).max() > 0.05  # the played elbow / knee: centimetres off


def _heading_turn(graph, a_nodes, b_nodes, posed, anchor):
    """(n, 4) the yaw that undoes the posing's heading keep (it turns the posed body so its hips face as the
    played node A's do): B's hips heading minus the posed hips heading, as a turn in B's `anchor` sensor frame."""
    roles = joint_roles(graph.skeleton)

    def heading(p):
        lateral = p[:, roles["left_hip"]] - p[:, roles["right_hip"]]
        return np.arctan2(-lateral[:, 2], lateral[:, 0])

    turn = yaw_about_up(heading(graph.node_positions_m[b_nodes].astype(float)) - heading(posed))
    frame = node_sensor_orientations(graph)[b_nodes, anchor]
    return quat.multiply(quat.conjugate(frame), quat.multiply(turn, frame))


@pytest.mark.parametrize("use_yaw", [True, False])
def test_a_played_forearm_that_fits_keeps_its_upper_arm(graph, use_yaw):
    """The lookup's share grows with the played forearm's misfit: a node posed onto its own orientations is
    played as it is (no misfit), and one posed onto a forearm 5 degrees off keeps (nearly) the hinge share's
    elbow where the lookup always on would move it."""
    q = node_sensor_orientations(graph)
    nodes = np.arange(0, graph.n_nodes, 37)
    poser = SegmentPoser(graph, list(range(6)), hinge_share=0.5, limb_prior_k=8)
    assert np.allclose(poser.pose(nodes, q[nodes], use_yaw=use_yaw), graph.node_positions_m[nodes], atol=1e-5)
    off = q[nodes].copy()
    off[:, RIGHT_FOREARM] = quat.multiply(quat.from_rotvec(np.array([0.0, 0.0, np.radians(5.0)])),
                                          off[:, RIGHT_FOREARM])
    always = SegmentPoser(graph, list(range(6)), hinge_share=0.5, limb_prior_k=8, prior_misfit_rad=1e-9)
    hinge_only = SegmentPoser(graph, list(range(6)), hinge_share=0.5)
    elbow = joint_roles(graph.skeleton)["right_elbow"]
    hinged = hinge_only.pose(nodes, off, use_yaw=use_yaw)[:, elbow]
    apart = np.linalg.norm(poser.pose(nodes, off, use_yaw=use_yaw)[:, elbow] - hinged, axis=-1).mean()
    apart_always = np.linalg.norm(always.pose(nodes, off, use_yaw=use_yaw)[:, elbow] - hinged, axis=-1).mean()
    assert apart < 0.05 * apart_always  # 5 deg of misfit: the lookup's share 1 - exp(-(5/40)^2) = 0.016


def test_the_tilt_only_lookup_does_not_see_the_sensors_yaws(graph):
    q = node_sensor_orientations(graph)
    nodes = np.arange(3, graph.n_nodes, 17)
    poser = SegmentPoser(graph, list(range(6)), hinge_share=0.5, limb_prior_k=8)
    other = (nodes * 7 + 11) % graph.n_nodes
    tilt = poser.pose(other, q[nodes], use_yaw=False)
    assert np.allclose(poser.pose(other, quat.multiply(yaw_about_up(YAWS), q[nodes]), use_yaw=False), tilt,
                       atol=1e-6)
    assert not np.allclose(tilt, SegmentPoser(graph, list(range(6)), hinge_share=0.5).pose(
        other, q[nodes], use_yaw=False), atol=1e-3)  # and the lookup moved the arms


def test_rotation_between_two_directions():
    rng = np.random.default_rng(3)
    u = rng.normal(size=(50, 3))
    v = rng.normal(size=(50, 3))
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    v[0] = -u[0]  # antiparallel: a half turn
    v[1] = u[1]   # the same: no turn
    r = rotation_between(u, v)
    assert np.allclose(quat.rotate(r, u), v, atol=1e-9)
    assert np.allclose(np.abs(r[1]), [1, 0, 0, 0], atol=1e-12)
    axis = np.cross(u[2:], v[2:])
    assert np.allclose(quat.rotate(r[2:], axis), axis, atol=1e-9)  # the shortest: about their common normal
