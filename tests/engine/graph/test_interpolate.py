"""Interpolated motions: slope-constrained DTW, alignment of similar clips, exact blends, graph wiring."""
from __future__ import annotations

import itertools

import numpy as np

from engine.graph.config import GraphConfig
from engine.graph.graph import EDGE_INTERP, NODE_INTERP, build_from_clips
from engine.graph.interpolate import find_alignments, slope_constrained_dtw
from engine.graph.poses import root_local
from engine.graph.viterbi import Observations, SearchWeights, ViterbiSearch

from .synth import gait_clip, observe, rigid_copy, walk_path


def brute_force_dtw(cost):
    """Cheapest (0,0)->(n-1,m-1) path with steps (1,1),(1,2),(2,1), by enumerating step sequences."""
    n, m = cost.shape
    best = (np.inf, None)
    steps = ((1, 1), (1, 2), (2, 1))
    for k in range(1, max(n, m)):
        for seq in itertools.product(steps, repeat=k):
            i = np.cumsum([0] + [s[0] for s in seq])
            j = np.cumsum([0] + [s[1] for s in seq])
            if i[-1] == n - 1 and j[-1] == m - 1:
                c = cost[i, j].sum()
                if c < best[0]:
                    best = (c, (i, j))
    return best


def test_dtw_matches_brute_force_and_respects_the_slope():
    rng = np.random.default_rng(0)
    for shape in ((6, 7), (7, 5), (6, 9)):
        cost = rng.uniform(0, 1, shape)
        cost[rng.uniform(size=shape) < 0.15] = np.inf
        cost[0, 0] = cost[-1, -1] = 0.5
        want = brute_force_dtw(cost)
        got = slope_constrained_dtw(cost)
        if want[1] is None:
            assert got is None
            continue
        assert np.isclose(cost[got].sum(), want[0])
        d = np.diff(np.stack(got), axis=1).T
        assert {tuple(s) for s in d} <= {(1, 1), (1, 2), (2, 1)}
    assert slope_constrained_dtw(np.ones((2, 6))) is None  # slope 5 is not allowed


CFG = GraphConfig(window_frames=5, transition_threshold_m=0.05, min_jump_frames=8, interp=True,
                  interp_threshold_m=0.01, interp_min_length_s=0.5)


def test_rigid_copies_align_on_their_periodic_diagonals_and_blend_exactly():
    a = gait_clip("a", n_frames=60, turn_rate=0.02, seed=1)
    b = rigid_copy(a, "b", angle_rad=1.1, shift_xz=(4.0, -2.0))
    als = find_alignments([a, b], CFG, np.ones(5))
    offsets = sorted({int(al.b[0]) - int(al.a[0]) for al in als})
    assert offsets == [-45, -30, -15, 0, 15, 30, 45]  # the gait repeats every 15 frames
    for al in als:
        assert np.all(np.diff(al.a) == 1) and np.all(np.diff(al.b) == 1)  # straight diagonals
    g = build_from_clips([a, b], CFG)
    interp = np.flatnonzero(g.node_kind == NODE_INTERP)
    assert len(interp) == sum(len(al.a) for al in als)
    # the diagonal blend of a clip with its rigid copy is the clip itself, placed where clip a is
    diag = interp[(g.node_clip[interp] == 0) & (g.node_clip2[interp] == 1)][:60]
    frames = g.node_frame[diag].astype(int)
    same = [k for k in range(len(diag)) if frames[k] == k]
    assert len(same) == 60
    assert np.allclose(g.node_positions_m[diag], a.positions_m, atol=1e-5)
    local = root_local(g.node_positions_m[diag].astype(float), g.node_ground_m[diag], g.node_heading_rad[diag])
    assert np.allclose(local, root_local(a.positions_m, a.ground_m, a.heading_rad), atol=1e-5)


def test_interpolated_nodes_are_wired_searchable_and_left_out_with_either_parent():
    a = gait_clip("a", n_frames=60, seed=1)
    b = gait_clip("b", n_frames=60, seed=2, phase=3)
    g = build_from_clips([a, b], CFG)
    entry = g.edge_kind == EDGE_INTERP
    assert entry.sum() > 0
    rng = np.random.default_rng(4)
    start = int(g.edge_src[np.flatnonzero(entry & (g.node_kind[g.edge_dst] == NODE_INTERP))[0]])
    nodes, edges = walk_path(g, max(start - 3, 0), 40, rng, prefer_kind=EDGE_INTERP)
    assert np.any(g.node_kind[nodes] == NODE_INTERP)
    acc, ground, heading = observe(g, nodes, edges, (0, 0), 0)
    res = ViterbiSearch(g, SearchWeights(acc=1.0)).run(Observations(acc, ground, heading))
    assert np.array_equal(res.nodes, nodes)
    for gone in (0, 1):
        h = g.without_clips([gone])
        assert not np.any(h.node_kind == NODE_INTERP)


def test_groups_whose_latest_cell_lies_left_of_the_start_are_handled():
    """An anti-diagonal group: the cell with the largest a+b is not below-right of the smallest one."""
    from engine.graph.clips import ClipData

    f = 40
    a = gait_clip("a", n_frames=f, seed=1)
    rev = ClipData("r", a.positions_m[::-1].copy(), a.contacts[::-1].copy(), a.heading_rad[::-1].copy(),
                   a.acc_g[::-1].copy(), label="walk")
    als = find_alignments([a, rev], CFG, np.ones(5))
    for al in als:
        assert np.all(np.diff(al.a) > 0) and np.all(np.diff(al.b) > 0)
