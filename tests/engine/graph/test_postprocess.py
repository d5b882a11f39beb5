"""One decided pose (issue 29), on a real synthesis (CMU sample, leave-one-out): the blend and the segment posing
act on rotations, the joint positions are their forward kinematics, and what `courtside synthesize` writes as
BVH is what it saves as poses (batch and --lag); foot IK on a Motion."""
from __future__ import annotations

import json

import numpy as np
import pytest

from engine.graph.decided import decided_poses
from engine.graph.evaluate import Noise, simulate_inputs
from engine.graph.orientation_pose import SegmentPoser
from engine.graph.orientation_term import node_sensor_orientations
from engine.graph.poses import blended_joint_positions, world_joint_positions
from engine.graph.postprocess import _contact_runs, fix_foot_skate, place_path
from engine.graph.search import ViterbiSearch
from engine.mocap import (Motion, SensorErrorModel, forward_kinematics, joint_roles, pose_joint_positions,
                          quaternions as quat, read_bvh)


@pytest.fixture(scope="module")
def synthesis(sample_graph, sample_clipdata, sample_motions):
    clips, _ = sample_clipdata
    ci = int(np.argmax([c.n_frames for c in clips]))  # the longest walk
    sub = sample_graph.without_clips([ci])
    sub.skeleton = sample_motions[0].skeleton  # the clips' own: the graph was built from plain arrays
    obs = simulate_inputs(clips[ci], tuple(range(6)), SensorErrorModel.seed000(), Noise(),
                          np.random.default_rng(0), 30.0)
    res = ViterbiSearch(sub).run(obs)
    return sub, res, sample_motions[0].skeleton


@pytest.fixture(scope="module")
def placed_graph(sample_motions):
    """A graph of every shipped clip but the first, its sensors at the standard placements."""
    from engine.graph.config import GraphConfig
    from engine.graph.graph import MotionGraph
    from engine.mocap import standard_placements

    return MotionGraph.build(sample_motions[1:], standard_placements(sample_motions[0].skeleton), GraphConfig())


def test_a_decided_path_pose_is_the_search_pose_and_its_rotations_give_its_joints(synthesis):
    g, res, skel = synthesis
    one = decided_poses(g, res.nodes[:, None], res.ground_m, res.heading_rad)
    assert np.abs(one.joint_positions_m - world_joint_positions(g, res.nodes, res.ground_m, res.heading_rad)).max() < 1e-5
    assert np.abs(pose_joint_positions(skel, one.root_m, one.local_rotations) - one.joint_positions_m).max() < 1e-9


def test_a_blend_of_poses_is_a_rotation_mean_close_to_the_mean_of_positions(synthesis):
    """Blending rotations keeps every bone's length (a mean of positions would not) and stays within a few
    millimetres of the positions' mean for the close poses a blend averages."""
    g, res, skel = synthesis
    blend = np.stack([res.nodes, np.r_[res.nodes[1:], res.nodes[-1]]], axis=1)  # each pose and the next one
    decided = decided_poses(g, blend, res.ground_m, res.heading_rad)
    mean_of_positions = blended_joint_positions(g, blend, res.ground_m, res.heading_rad)
    gap_cm = 100 * np.linalg.norm(decided.joint_positions_m - mean_of_positions, axis=-1)
    assert 0 < gap_cm.mean() < 1.0
    bones = np.linalg.norm(np.diff(decided.joint_positions_m[:, [0, 1]], axis=1), axis=-1)
    played = np.linalg.norm(np.diff(world_joint_positions(g, res.nodes, res.ground_m, res.heading_rad)[:, [0, 1]],
                                    axis=1), axis=-1)
    assert np.allclose(bones, played, atol=1e-6)


def test_posing_turns_rotations_whose_joints_are_the_posed_positions(placed_graph):
    """`SegmentPoser.posed` turns the joints' rotations with the same turns as their positions (hinge share,
    looked-up upper limbs, heading kept): the forward kinematics of the posed rotations is the posed positions."""
    g, skel = placed_graph, placed_graph.skeleton
    poser = SegmentPoser(g, list(range(6)), hinge_share=0.5, limb_prior_k=16)
    nodes = np.arange(0, g.n_nodes, 41)
    twist = quat.from_rotvec(np.random.default_rng(1).normal(0.0, 0.5, (len(nodes), 6, 3)))
    measured = quat.multiply(twist, node_sensor_orientations(g)[nodes])
    for use_yaw in (True, False):
        pts, glob = poser.posed(nodes, measured, use_yaw=use_yaw)
        local = glob.copy()
        local[:, 1:] = quat.multiply(quat.conjugate(glob[:, skel.parents[1:]]), glob[:, 1:])
        fk = pose_joint_positions(skel, g.node_root_m[nodes], local)
        assert np.abs(fk - pts).max() < 1e-5
        assert np.abs(pts - g.node_positions_m[nodes]).max() > 0.05  # the posing moved joints


def test_foot_ik_pins_reachable_contacts_and_keeps_bones(synthesis):
    g, res, skel = synthesis
    root, rots = place_path(g, res.nodes, res.ground_m, res.heading_rad)
    free = Motion(skel, g.config.fps, root, rots)
    contacts = g.node_contacts[res.nodes]
    pos, _ = forward_kinematics(fix_foot_skate(free, contacts))
    pos_free, _ = forward_kinematics(free)
    roles = joint_roles(skel)
    for col, side in enumerate(("left", "right")):
        hip, knee, ankle = (roles[f"{side}_{p}"] for p in ("hip", "knee", "ankle"))
        reach = (np.linalg.norm(pos[:, knee] - pos[:, hip], axis=1)
                 + np.linalg.norm(pos[:, ankle] - pos[:, knee], axis=1))
        for a, b in _contact_runs(contacts[:, col]):
            k = np.arange(a, b - 3)  # before the easing-out frames
            target = pos_free[a, ankle]
            reachable = np.linalg.norm(target - pos[k, hip], axis=1) < reach[k] - 1e-3
            err = np.linalg.norm(pos[k, ankle] - target, axis=1)
            assert np.all(err[reachable] < 1e-6)
        assert np.allclose(reach, np.linalg.norm(pos_free[:, knee] - pos_free[:, hip], axis=1)
                           + np.linalg.norm(pos_free[:, ankle] - pos_free[:, knee], axis=1))


@pytest.mark.parametrize("lag", [None, "1.0"])
def test_synthesize_writes_the_saved_poses_as_bvh_and_posing_changes_the_file(tmp_path, sample_motions, lag,
                                                                            placed_graph, capsys):
    """`courtside synthesize` on a take with orientations: the forward kinematics of the BVH it writes equals the
    joint positions it saves (--save-poses, the console's format) within 1 mm, batch and --lag; `--segment-pose
    0` and `1` write different files (the posing reaches the file)."""
    from engine.graph.cli import synthesize_main
    from engine.mocap import standard_placements, virtual_accelerometers
    from engine.mocap.orientation import to_device_earth, virtual_orientations
    from engine.stream.poses_file import load_poses

    graph = placed_graph
    graph.save(tmp_path / "g.npz")
    motion = sample_motions[0].slice(0, 150)
    placements = standard_placements(motion.skeleton)
    np.savez(tmp_path / "take.npz", acc_g=virtual_accelerometers(motion, placements), fps=motion.fps,
             sensor_names=np.array([p.name for p in placements]),
             quat_wxyz=to_device_earth(virtual_orientations(motion, placements), np.linspace(-2, 2, 6)))
    written = {}
    for gain in ("0", "1"):
        out, saved = tmp_path / f"out{gain}.bvh", tmp_path / f"poses{gain}.npz"
        argv = ["--graph", str(tmp_path / "g.npz"), "--input", str(tmp_path / "take.npz"), "-o", str(out),
                "--save-poses", str(saved), "--segment-pose", gain] + ([] if lag is None else ["--lag", lag])
        assert synthesize_main(argv) == 0
        json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        bvh_joints = forward_kinematics(read_bvh(out, scale="cm"))[0]
        poses = load_poses(saved)
        assert bvh_joints.shape == poses.joint_positions_m.shape
        assert np.abs(bvh_joints - poses.joint_positions_m).max() < 1e-3
        assert np.abs(pose_joint_positions(graph.skeleton, poses.root_m, poses.local_rotations)
                      - poses.joint_positions_m).max() < 1e-9
        written[gain] = out.read_bytes()
    assert written["0"] != written["1"]
