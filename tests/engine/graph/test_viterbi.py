"""Viterbi search against exact answers: noiseless walks are recovered, noisy ones match exhaustive search."""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.config import GraphConfig
from engine.graph.geometry import wrap_angle
from engine.graph.graph import build_from_clips
from engine.graph.parts import EDGE_TRANSITION
from engine.graph.viterbi import Constraint, Observations, SearchWeights
from engine.graph.search import ViterbiSearch

from .synth import gait_clip, observe, rigid_copy, walk_path

CFG = GraphConfig(window_frames=5, transition_threshold_m=0.05, min_jump_frames=8)


@pytest.fixture(scope="module")
def graph():
    a = gait_clip("a", n_frames=80, turn_rate=0.02, seed=1, label="walk")
    b = rigid_copy(a, "b", angle_rad=1.1, shift_xz=(4.0, -2.0))
    b.label = "run"
    return build_from_clips([a, b], CFG)


def all_paths(g, n_samples):
    """Every path of n_samples nodes, as (nodes, edges) arrays (edges[0] = -1)."""
    out = {int(s): [] for s in range(g.n_nodes)}
    for e, s in enumerate(g.edge_src):
        out[int(s)].append(e)
    paths = [([n], [-1]) for n in range(g.n_nodes)]
    for _ in range(n_samples - 1):
        paths = [(n + [int(g.edge_dst[e])], es + [e]) for n, es in paths for e in out[n[-1]]]
    return paths


def acc_cost(g, nodes, edges, acc, w):
    rows = np.r_[g.node_arrival[nodes[0]], g.edge_meta[edges[1:]]]
    return w * np.mean(np.sum((g.meta_acc_g[rows].astype(float) - acc) ** 2, axis=2), axis=1).sum()


def test_noiseless_walk_with_transitions_is_recovered_exactly(graph):
    rng = np.random.default_rng(5)
    nodes, edges = walk_path(graph, 2, 70, rng, prefer_kind=EDGE_TRANSITION)
    assert np.sum(graph.edge_kind[edges[1:]] == EDGE_TRANSITION) >= 3
    acc, ground, heading = observe(graph, nodes, edges, ground0=(1.0, 2.0), heading0=0.3)
    first_only = Observations(acc, np.r_[ground[:1], np.full((len(acc) - 1, 2), np.nan)],
                              np.r_[heading[:1], np.full(len(acc) - 1, np.nan)])
    res = ViterbiSearch(graph, SearchWeights(acc=1.0, position=0, heading=0)).run(first_only)
    assert np.array_equal(res.nodes, nodes) and np.array_equal(res.edges[1:], edges[1:])
    assert res.cost < 1e-9
    # accelerometer-only (Markov) search tracks no global state; the path is integrated from the first sample
    assert np.allclose(res.ground_m, ground, atol=1e-9)
    assert np.allclose(wrap_angle(res.heading_rad - heading), 0, atol=1e-9)
    # with all three modalities the same path comes out and the carried global state is the truth
    # (the search carries it in float32: 20 um / 20 urad is float32 resolution over a few metres and steps)
    res = ViterbiSearch(graph).run(Observations(acc, ground, heading))
    assert np.array_equal(res.nodes, nodes)
    assert np.allclose(res.ground_m, ground, atol=2e-5)
    assert np.allclose(wrap_angle(res.heading_rad - heading), 0, atol=2e-5)


def test_accelerometer_only_search_is_optimal_against_exhaustive_search(graph):
    rng = np.random.default_rng(7)
    sub = graph.without_clips([1])  # ~80 nodes: exhaustive search stays small
    t = 6
    nodes, edges = walk_path(sub, 10, t, rng)
    acc, _, _ = observe(sub, nodes, edges, (0, 0), 0)
    acc = acc + rng.normal(0, 0.8, acc.shape)  # noisy: the truth is no longer necessarily the optimum
    w = 0.5
    costs = [(acc_cost(sub, np.array(n), np.array(e), acc, w), n) for n, e in all_paths(sub, t)]
    best_cost, best_nodes = min(costs, key=lambda c: c[0])
    res = ViterbiSearch(sub, SearchWeights(acc=w)).run(Observations(acc))
    assert res.cost == pytest.approx(best_cost, rel=1e-6)  # float32 GEMV
    assert res.nodes.tolist() == best_nodes


def test_constraints_rank_before_cost(graph):
    """With a 'run' requirement around one frame, the best path breaks the fewest constraints, then has the
    lowest cost among those -- checked against exhaustive search over a small graph."""
    rng = np.random.default_rng(11)
    small = build_from_clips([gait_clip("a", n_frames=40, seed=1, label="walk"),
                              gait_clip("b", n_frames=40, seed=2, label="run")], CFG)
    t = 5
    nodes, edges = walk_path(small, 3, t, rng)  # a walk path: starts in clip "a"
    acc, _, _ = observe(small, nodes, edges, (0, 0), 0)
    run = small.label_mask("run")
    cons = [Constraint(frame=3, tolerance_frames=1, node_mask=run)]
    res_free = ViterbiSearch(small, SearchWeights(acc=1)).run(Observations(acc))
    assert np.array_equal(res_free.nodes, nodes) and not run[nodes[2:5]].all()
    res = ViterbiSearch(small, SearchWeights(acc=1)).run(Observations(acc), cons)

    def broken(n):
        return int(sum(not run[n[k]] for k in (2, 3, 4)))
    scored = [(broken(n), acc_cost(small, np.array(n), np.array(e), acc, 1.0), n) for n, e in all_paths(small, t)]
    want = min(scored, key=lambda s: (s[0], s[1]))
    assert res.broken_constraints == want[0]
    assert res.cost == pytest.approx(want[1], rel=1e-6)
    assert res.nodes.tolist() == want[2]


def test_survivor_pruning_keeps_the_answer_and_compresses(graph):
    rng = np.random.default_rng(3)
    nodes, edges = walk_path(graph, 0, 60, rng, prefer_kind=EDGE_TRANSITION)
    acc, ground, heading = observe(graph, nodes, edges, (0, 0), 0)
    acc = acc + rng.normal(0, 0.5, acc.shape)
    obs = Observations(acc, ground + rng.normal(0, 0.05, ground.shape), heading)
    ref = ViterbiSearch(graph, prune_every=0).run(obs)
    for every in (1, 7):
        res = ViterbiSearch(graph, prune_every=every).run(obs)
        assert np.array_equal(res.nodes, ref.nodes) and res.cost == ref.cost
        assert res.compression_ratio > 5.0
    assert res.lattice_entries * res.compression_ratio == pytest.approx(graph.n_nodes * (len(acc) - 1))


def test_a_take_without_an_initial_camera_fix_starts_at_the_first_fix(graph):
    rng = np.random.default_rng(5)
    nodes, edges = walk_path(graph, 2, 60, rng, prefer_kind=EDGE_TRANSITION)
    acc, ground, heading = observe(graph, nodes, edges, ground0=(7.0, -4.0), heading0=2.0)
    late = 6
    pos = ground.copy()
    head = heading.copy()
    pos[:late] = np.nan
    head[:late] = np.nan
    res = ViterbiSearch(graph, SearchWeights(acc=1.0)).run(Observations(acc, pos, head))
    assert np.array_equal(res.nodes, nodes)
    # from the first fix on, the carried track is the truth (before it, paths had nothing to be placed by);
    # float32 state: to 20 um
    assert np.allclose(res.ground_m[late:], ground[late:], atol=2e-5)


def test_survivor_pruning_work_stays_linear_in_the_take_length(sample_graph_msv, sample_clipdata, monkeypatch):
    """Each column is re-pruned only until it was pruned at PRUNE_HORIZON samples old, so a long take costs
    O(T) column passes; walking back to an exact match every time grew like T^2 (38,921 passes here)."""
    from engine.graph import viterbi

    clips, _ = sample_clipdata
    acc = np.concatenate([c.acc_g for c in clips] * 3)[:1500]
    ground = np.concatenate([c.ground_m - c.ground_m[0] for c in clips] * 3)[:1500]
    heading = np.concatenate([c.heading_rad for c in clips] * 3)[:1500]
    obs = Observations(acc, ground, heading)
    monkeypatch.setattr(viterbi, "PRUNE_HORIZON", 32)
    passes = []
    lookup = viterbi.ViterbiLattice._lookup
    monkeypatch.setattr(viterbi.ViterbiLattice, "_lookup", lambda self, col, nodes: passes.append(1) or
                        lookup(self, col, nodes))
    res = ViterbiSearch(sample_graph_msv, prune_every=4, kernel="numpy").run(obs)
    assert len(passes) <= len(acc) * (32 // 4 + 3)
    ref = ViterbiSearch(sample_graph_msv, prune_every=0, kernel="numpy").run(obs)
    assert np.array_equal(res.nodes, ref.nodes) and res.cost == ref.cost
