"""Post-processing on a real synthesis (CMU sample, leave-one-out): placement, blending, foot IK, BVH out."""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.evaluate import Noise, simulate_inputs
from engine.graph.poses import world_joint_positions
from engine.graph.postprocess import _contact_runs, path_to_motion, transition_times
from engine.graph.search import ViterbiSearch
from engine.mocap import SensorErrorModel, forward_kinematics, joint_roles, read_bvh, write_bvh


@pytest.fixture(scope="module")
def synthesis(sample_graph, sample_clipdata, sample_motions):
    clips, _ = sample_clipdata
    ci = int(np.argmax([c.n_frames for c in clips]))  # the longest walk
    sub = sample_graph.without_clips([ci])
    obs = simulate_inputs(clips[ci], tuple(range(6)), SensorErrorModel.seed000(), Noise(),
                          np.random.default_rng(0), 30.0)
    res = ViterbiSearch(sub).run(obs)
    return sub, res, sample_motions[0].skeleton


def test_placed_motion_reproduces_the_search_poses(synthesis):
    g, res, skel = synthesis
    raw = path_to_motion(g, skel, res.nodes, res.edges, res.ground_m, res.heading_rad, blend=False, foot_ik=False)
    pos, _ = forward_kinematics(raw)
    assert np.abs(pos - world_joint_positions(g, res.nodes, res.ground_m, res.heading_rad)).max() < 1e-5


def test_blending_shrinks_the_jumps_at_transitions(synthesis):
    g, res, skel = synthesis
    tt = transition_times(g, res.edges)
    assert len(tt) >= 3
    jumps = []
    for blend in (False, True):
        m = path_to_motion(g, skel, res.nodes, res.edges, res.ground_m, res.heading_rad, blend=blend, foot_ik=False)
        pos, _ = forward_kinematics(m)
        jumps.append(np.linalg.norm(np.diff(pos, axis=0), axis=2).max(axis=1)[tt - 1])
    assert jumps[1].max() < jumps[0].max()
    assert jumps[1].mean() < 0.8 * jumps[0].mean()


def test_foot_ik_pins_reachable_contacts_and_keeps_bones(synthesis):
    g, res, skel = synthesis
    m = path_to_motion(g, skel, res.nodes, res.edges, res.ground_m, res.heading_rad)
    free = path_to_motion(g, skel, res.nodes, res.edges, res.ground_m, res.heading_rad, foot_ik=False)
    pos, _ = forward_kinematics(m)
    pos_free, _ = forward_kinematics(free)
    roles = joint_roles(skel)
    contacts = g.node_contacts[res.nodes]
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


def test_written_bvh_reads_back(tmp_path, synthesis):
    g, res, skel = synthesis
    m = path_to_motion(g, skel, res.nodes, res.edges, res.ground_m, res.heading_rad)
    write_bvh(tmp_path / "out.bvh", m)
    back = read_bvh(tmp_path / "out.bvh")
    assert back.n_frames == m.n_frames
    assert np.abs(forward_kinematics(back)[0] - forward_kinematics(m)[0]).max() < 1e-4
