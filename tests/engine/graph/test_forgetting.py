"""The forgetting search (SearchWeights.forgetting / decision_frames / blend_paths, issue 11's pose criterion),
on synthetic graphs with exact answers.

A held-out take is never one database path. The seed-000 Viterbi must explain the whole take with one graph
path, so when the take switches to a motion it cannot reach it keeps playing the old clip; a forgetting search
decides each sample from the paths that match the last few samples and follows the switch. The blended output
averages the best paths' poses: two database clips that read alike but bend a joint either way of the truth
average to the truth exactly, where any single path is off by the bend.
"""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.clips import ClipData
from engine.graph.config import GraphConfig
from engine.graph.graph import build_from_clips
from engine.graph.online import FixedLagSynthesizer
from engine.graph.poses import blended_joint_positions, root_local, world_joint_positions
from engine.graph.viterbi import Observations, SearchWeights
from engine.graph.search import ViterbiSearch
from engine.graph.warp import RootWarp

from .synth import gait_clip

NO_TRANSITIONS = GraphConfig(window_frames=5, transition_threshold_m=1e-9, min_jump_frames=8)
SWITCH = 50  # the take plays clip a's frames 0..49, then clip b's frames 50..79


@pytest.fixture(scope="module")
def two_chains():
    """Two clips with no transition between them (two disconnected chains) and a take that switches clips."""
    a = gait_clip("a", n_frames=90, seed=1)
    b = gait_clip("b", n_frames=90, period=12, seed=2)
    g = build_from_clips([a, b], NO_TRANSITIONS)
    assert not np.any(g.node_clip[g.edge_src] != g.node_clip[g.edge_dst])  # no path leads from a to b
    truth = np.r_[np.arange(SWITCH), 90 + np.arange(SWITCH, 80)]  # graph nodes: a's frames, then b's
    acc = g.meta_acc_g[g.node_arrival[truth]].astype(float)
    return g, truth, Observations(acc)


def test_exact_viterbi_cannot_follow_a_switch_the_graph_lacks(two_chains):
    """The old behaviour: one path for the whole take, so the 30 samples after the switch stay on clip a."""
    g, truth, obs = two_chains
    res = ViterbiSearch(g, SearchWeights(1.0, 0.0, 0.0)).run(obs)
    assert np.array_equal(res.nodes[:SWITCH], truth[:SWITCH])
    assert np.all(g.node_clip[res.nodes[SWITCH:]] == 0)


def test_forgetting_search_follows_the_switch_exactly(two_chains):
    g, truth, obs = two_chains
    weights = SearchWeights(1.0, 0.0, 0.0, forgetting=0.5, decision_frames=2)
    res = ViterbiSearch(g, weights).run(obs)
    settle = 4  # samples around the switch where the decision (made 2 samples later) may still be ambiguous
    assert np.array_equal(res.nodes[:SWITCH - settle], truth[:SWITCH - settle])
    assert np.array_equal(res.nodes[SWITCH + settle:], truth[SWITCH + settle:])
    jumps = np.flatnonzero(res.edges[1:] < 0) + 1  # the decoder changed clips without a graph edge: marked -1
    assert len(jumps) >= 1 and np.all(np.abs(jumps - SWITCH) <= settle)


@pytest.mark.parametrize("kernel", ["numba", "numpy"])
def test_batch_equals_fixed_lag_bit_for_bit(two_chains, kernel):
    """Offline (batch) and live (fixed lag, any lag >= the decision lag) decide every sample identically, with
    camera terms, root warping and the blended pose; numba and the numpy reference agree."""
    g, _, obs = two_chains
    rng = np.random.default_rng(3)
    n = obs.n_samples
    ground = np.cumsum(rng.normal(0, 0.03, (n, 2)), axis=0)
    heading = np.cumsum(rng.normal(0, 0.02, n))
    ground[5:9] = np.nan  # a camera gap
    full = Observations(obs.acc_g + rng.normal(0, 0.3, obs.acc_g.shape), ground, heading)
    weights = SearchWeights(1.0, 1.0, 0.3, forgetting=0.8, decision_frames=3, blend_paths=3)
    warp = RootWarp()
    batch = ViterbiSearch(g, weights, kernel=kernel, warp=warp).run(full)
    reference = ViterbiSearch(g, weights, kernel="numpy", warp=warp).run(full)
    assert np.array_equal(batch.nodes, reference.nodes) and np.array_equal(batch.ground_m, reference.ground_m)
    for lag_s in (3 / g.config.fps, 2.0):
        syn = FixedLagSynthesizer(g, lag_s, weights, kernel=kernel, warp=warp, confidence_reference=1.0)
        assert syn.decision_lag == 3  # a forgetting search decides after decision_frames ...
        out = []
        for t in range(n):
            got = syn.push(full.acc_g[t], full.position_m[t], full.heading_rad[t])
            assert [p.t for p in got] == ([t - syn.lag] if t >= syn.lag else [])  # ... and emits after the lag
            out += got
        out += syn.flush()
        assert [p.t for p in out] == list(range(n))
        assert np.array_equal([p.node for p in out], batch.nodes)
        assert np.array_equal([p.edge for p in out], batch.edges)
        assert np.array_equal(np.array([p.ground_m for p in out]), batch.ground_m)
        assert np.array_equal(np.array([p.heading_rad for p in out]), batch.heading_rad)
        assert np.array_equal(np.stack([p.blend_nodes for p in out]), batch.blend_nodes)


def _bent(clip: ClipData, name: str, dx_m: float) -> ClipData:
    """The clip with its head joint moved sideways by dx_m (the clip walks along +Z: x is sideways in its root
    frame); same readings."""
    pos = clip.positions_m.copy()
    pos[:, 1, 0] += dx_m
    return ClipData(name=name, positions_m=pos, contacts=clip.contacts, heading_rad=clip.heading_rad,
                    acc_g=clip.acc_g, label=clip.label, acc_slow_g=clip.acc_slow_g, acc_fast_g=clip.acc_fast_g)


def test_blend_of_two_equally_good_paths_is_the_truth_where_one_path_is_off():
    base = gait_clip("truth", n_frames=60, seed=4)
    g = build_from_clips([_bent(base, "left", 0.05), _bent(base, "right", -0.05), gait_clip("other", 60, seed=5)],
                         NO_TRANSITIONS)
    frames = np.arange(60)
    obs = Observations(g.meta_acc_g[g.node_arrival[frames]].astype(float))  # clips left and right read alike
    single = ViterbiSearch(g, SearchWeights(1.0, 0.0, 0.0, forgetting=0.7, decision_frames=2)).run(obs)
    blended = ViterbiSearch(g, SearchWeights(1.0, 0.0, 0.0, forgetting=0.7, decision_frames=2,
                                             blend_paths=2)).run(obs)
    assert set(np.unique(g.node_clip[blended.blend_nodes])) == {0, 1}  # the two bent clips, never the other
    assert np.array_equal(np.sort(g.node_frame[blended.blend_nodes], axis=1), np.repeat(frames[:, None], 2, 1))
    truth_local = root_local(base.positions_m, base.ground_m, base.heading_rad)
    one = root_local(world_joint_positions(g, single.nodes, single.ground_m, single.heading_rad), single.ground_m,
                     single.heading_rad)
    two = root_local(blended_joint_positions(g, blended.blend_nodes, blended.ground_m, blended.heading_rad),
                     blended.ground_m, blended.heading_rad)
    assert np.allclose(np.abs(one - truth_local)[:, 1, 0], 0.05, atol=1e-6)  # any single path: off by the bend
    assert np.allclose(two, truth_local, atol=1e-6)  # the blend: the truth


def test_settings_are_checked():
    with pytest.raises(ValueError, match="forgetting"):
        SearchWeights(forgetting=0.0)
    with pytest.raises(ValueError, match="blend_paths"):
        SearchWeights(blend_paths=4)  # a blend needs the per-sample decisions of a forgetting search
    preset = SearchWeights.camera_following()
    assert preset.forgets and preset.blend_paths > 1 and SearchWeights().forgetting == 1.0


def test_blended_bvh_pose_is_the_rotation_midpoint(sample_graph):
    """The written/streamed pose of a blend (postprocess.place_blend): one column = the path's own pose; two
    columns = every joint rotation halfway between the two (the chordal mean of two unit quaternions is their
    slerp midpoint), the root halfway between the placed roots."""
    from engine.graph.postprocess import place_blend, place_path
    from engine.mocap import quaternions as quat

    g = sample_graph
    a, b = np.arange(0, 20), np.arange(40, 60)
    ground = np.stack([np.linspace(0, 1, 20), np.zeros(20)], axis=1)
    heading = np.linspace(0.0, 0.5, 20)
    root_a, rots_a = place_path(g, a, ground, heading)
    root_b, rots_b = place_path(g, b, ground, heading)
    root, rots = place_blend(g, a[:, None], ground, heading)
    assert np.allclose(root, root_a) and np.allclose(np.abs(np.sum(rots * rots_a, -1)), 1.0)
    root, rots = place_blend(g, np.stack([a, b], axis=1), ground, heading)
    assert np.allclose(root, 0.5 * (root_a + root_b))
    mid = quat.slerp(rots_a, rots_b, np.full(rots_a.shape[:-1], 0.5))
    assert np.allclose(np.abs(np.sum(rots * mid, -1)), 1.0, atol=1e-9)


def test_forgetting_option_on_the_command_line():
    """--forgetting replaces the preset's value; 1 is seed 000's search (one path, no blend); out of range is a
    one-line error."""
    import argparse

    from engine.errors import CourtsideError
    from engine.graph.cli import add_search_args, weights_from_args

    p = argparse.ArgumentParser()
    add_search_args(p)
    assert weights_from_args(p.parse_args([]), RootWarp()) == SearchWeights.camera_following()
    exact = weights_from_args(p.parse_args(["--forgetting", "1", "--weights", "0.5", "10", "3"]), RootWarp())
    assert (exact.acc, exact.position, exact.heading, exact.forgets, exact.blend_paths) == (0.5, 10, 3, False, 1)
    assert weights_from_args(p.parse_args([]), RootWarp.off()) == SearchWeights()
    with pytest.raises(CourtsideError, match="--forgetting"):
        weights_from_args(p.parse_args(["--forgetting", "0"]), RootWarp())


def test_a_take_that_outlasts_every_path_is_one_clear_error_not_a_crash(two_chains):
    """Two chains with no transitions: a take longer than either runs every path into a dead end. The search
    says so (the evaluation's tiny held-out graphs hit this as a reshape ValueError inside the pose blend)."""
    from engine.graph.viterbi import PathsExhaustedError

    from dataclasses import replace

    g, _, _ = two_chains
    forward = g.edge_dst == g.edge_src + 1  # the clips' own frame order only: each clip one chain into a dead end
    g = replace(g, edge_src=g.edge_src[forward], edge_dst=g.edge_dst[forward], edge_kind=g.edge_kind[forward],
                edge_meta=g.edge_meta[forward])
    acc = np.repeat(g.meta_acc_g[g.node_arrival[:1]].astype(float), 3 * g.n_nodes, axis=0)
    weights = SearchWeights(forgetting=0.9, decision_frames=6, blend_paths=8)
    with pytest.raises(PathsExhaustedError, match="dead end"):
        ViterbiSearch(g, weights).run(Observations(acc))
