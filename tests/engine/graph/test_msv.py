"""Motion speed variations: where they are added, what their metadata says, and that the search uses them."""
from __future__ import annotations

import numpy as np

from engine.graph.config import GraphConfig
from engine.graph.graph import build_from_clips
from engine.graph.parts import EDGE_NATURAL, EDGE_SLOWDOWN, EDGE_SPEEDUP, NODE_SLOW
from engine.graph.metadata import advance
from engine.graph.viterbi import Observations, SearchWeights
from engine.graph.search import ViterbiSearch

from .synth import gait_clip, observe, walk_path

CFG = GraphConfig(window_frames=5, transition_threshold_m=0.05, min_jump_frames=8, msv=True)


def jumping_clip():
    clip = gait_clip("a", n_frames=50, turn_rate=0.03, seed=4)
    clip.contacts[20:26] = False  # a flight phase
    return clip


def test_msv_nodes_and_edges_avoid_flight_and_match_counts():
    clip = jumping_clip()
    g = build_from_clips([clip], CFG)
    grounded = clip.contacts.any(axis=1)
    slow_f = np.flatnonzero(grounded[:-1] & grounded[1:])
    slow = np.flatnonzero(g.node_kind == NODE_SLOW)
    assert np.array_equal(g.node_frame[slow], slow_f + 0.5)
    up = g.edge_kind == EDGE_SPEEDUP
    src_f = g.node_frame[g.edge_src[up]].astype(int)
    assert np.array_equal(np.sort(src_f), np.flatnonzero(grounded[:-2] & grounded[1:-1] & grounded[2:]))
    assert np.all(g.node_frame[g.edge_dst[up]] == src_f + 2)
    touched = np.r_[g.node_frame[g.edge_src[~(g.edge_kind == EDGE_NATURAL)]],
                    g.node_frame[g.edge_dst[~(g.edge_kind == EDGE_NATURAL)]]]
    # no MSV node or edge lies inside the flight phase (frames 20..25 and the half frames around them)
    assert not np.any((touched >= 19.5) & (touched <= 25.5))


def test_half_speed_steps_compose_to_the_natural_step():
    g = build_from_clips([jumping_clip()], CFG)
    slow = np.flatnonzero(g.node_kind == NODE_SLOW)
    for s in slow[:5]:
        e_in = np.flatnonzero((g.edge_dst == s) & (g.edge_kind == EDGE_SLOWDOWN))[0]
        e_out = np.flatnonzero((g.edge_src == s) & (g.edge_kind == EDGE_SLOWDOWN))[0]
        f = g.edge_src[e_in]
        nat = np.flatnonzero((g.edge_src == f) & (g.edge_dst == f + 1))[0]
        p, h = advance(np.zeros(2), 0.7, g.meta_dpos_m[g.edge_meta[e_in]], g.meta_dheading_rad[g.edge_meta[e_in]])
        p, h = advance(p, h, g.meta_dpos_m[g.edge_meta[e_out]], g.meta_dheading_rad[g.edge_meta[e_out]])
        q, k = advance(np.zeros(2), 0.7, g.meta_dpos_m[g.edge_meta[nat]], g.meta_dheading_rad[g.edge_meta[nat]])
        assert np.allclose(p, q, atol=1e-12) and np.isclose(h, k)


def test_search_follows_a_speed_varied_walk():
    g = build_from_clips([gait_clip("a", n_frames=60, seed=1), gait_clip("b", n_frames=60, seed=2)], CFG)
    rng = np.random.default_rng(0)
    for kind in (EDGE_SLOWDOWN, EDGE_SPEEDUP):
        nodes, edges = walk_path(g, 1, 25, rng, prefer_kind=kind)
        assert np.sum(g.edge_kind[edges[1:]] == kind) >= 8
        acc, ground, heading = observe(g, nodes, edges, (0.0, 0.0), 0.0)
        res = ViterbiSearch(g, SearchWeights(acc=1.0)).run(Observations(acc, ground, heading))
        assert np.array_equal(res.nodes, nodes)
