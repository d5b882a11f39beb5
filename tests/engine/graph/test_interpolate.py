"""Interpolated motions: slope-constrained DTW, alignment of similar clips, exact blends, graph wiring."""
from __future__ import annotations

import itertools

from dataclasses import replace

import numpy as np

from engine.graph.config import GraphConfig
from engine.graph.graph import build_from_clips
from engine.graph.parts import EDGE_INTERP, NODE_INTERP
from engine.graph.interpolate import find_alignments, slope_constrained_dtw
from engine.graph.poses import root_local
from engine.graph.viterbi import Observations, SearchWeights
from engine.graph.search import ViterbiSearch

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
    g = build_from_clips([a, b], replace(CFG, interp_max_share=None))  # every alignment (2x the frames)
    interp = np.flatnonzero(g.node_kind == NODE_INTERP)
    assert len(interp) == sum(len(al.a) for al in als)
    capped = build_from_clips([a, b], CFG)  # the default cap: half the database's 120 frames
    rep = capped.build_report["interpolation"]
    assert rep["frames_found"] == 240 and rep["cap_frames"] == 60
    assert (capped.node_kind == NODE_INTERP).sum() == rep["frames_kept"] <= 60
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


def test_blend_of_a_real_clip_with_its_rigid_copy_reads_the_clip_s_own_sensors(sample_motions):
    """With a sensor model (engine.mocap virtual sensors) the blended motion gets simulated readings; blending a
    CMU walk with a turned and shifted copy of itself gives back the walk, so the readings must be the walk's."""
    from engine.graph.mocap_adapter import clips_from_motions, mocap_sensor_model
    from engine.mocap import Motion, standard_placements
    from engine.mocap import quaternions as quat

    walk = max(sample_motions, key=lambda m: m.n_frames)
    yaw = 0.9
    q = quat.from_rotvec(np.array([0.0, yaw, 0.0]))
    root = walk.root_positions_m.copy()
    root[:, [0, 2]] = np.stack([root[:, 0] * np.cos(yaw) + root[:, 2] * np.sin(yaw),
                                -root[:, 0] * np.sin(yaw) + root[:, 2] * np.cos(yaw)], axis=1) + [3.0, -1.0]
    rots = walk.rotations.copy()
    rots[:, 0] = quat.multiply(q, rots[:, 0])
    copy = Motion(walk.skeleton, walk.fps, root, rots, "copy")
    cfg = GraphConfig(interp=True, interp_threshold_m=0.01)
    placements = standard_placements(walk.skeleton)
    clips = clips_from_motions([walk, copy], placements, cfg)
    clips[1].acc_g = clips[1].acc_g + 1.0  # averaging parents would now be off by 0.5 g; simulating is not
    g = build_from_clips(clips, cfg, mocap_sensor_model(walk.skeleton, placements, cfg.fps))
    diag = np.flatnonzero((g.node_kind == NODE_INTERP) & (g.node_clip == 0) & (g.node_clip2 == 1))
    frames = g.node_frame[diag].astype(int)
    chain = diag[np.flatnonzero(np.diff(frames) == 1)]
    assert len(chain) > 30
    inner = chain[2:-2]  # away from the chain ends, where finite differences copy their neighbours
    got = g.meta_acc_g[g.node_arrival[inner]]
    want = clips[0].acc_g[g.node_frame[inner].astype(int)]
    assert np.abs(got - want).max() < 1e-3  # float32 storage


def test_cap_keeps_the_cleanest_alignments_within_the_frame_budget():
    from engine.graph.interpolate import Alignment, cap_alignments

    def al(n, d):
        return Alignment(0, 1, np.arange(n), np.arange(n), d)
    found = [al(30, 0.04), al(20, 0.01), al(25, 0.02), al(10, 0.03)]
    kept = cap_alignments(found, 50)
    assert [a.distance_m for a in kept] == [0.01, 0.02]  # 20 + 25 = 45; the 0.03 one (10) would make 55
    assert [a.distance_m for a in cap_alignments(found, 55)] == [0.01, 0.02, 0.03]
