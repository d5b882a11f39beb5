"""The component step (engine/graph/components.py) on synthetic graphs with a known loop trap."""
from __future__ import annotations

import numpy as np

from engine.graph.clips import ClipData
from engine.graph.components import largest_component
from engine.graph.config import GraphConfig
from engine.graph.graph import build_from_clips
from engine.graph.parts import EDGE_TRANSITION
from engine.graph.transitions import idle_frames

from .synth import gait_clip, rigid_copy


def _concat(name: str, first: ClipData, second: ClipData) -> ClipData:
    """One clip playing `first` then `second` (a natural edge joins them)."""
    cat = {k: np.concatenate([getattr(first, k), getattr(second, k)])
           for k in ("positions_m", "contacts", "heading_rad", "acc_g", "acc_fast_g")}
    slow = np.concatenate([first.acc_slow_g, second.acc_slow_g[:1], second.acc_slow_g])
    return ClipData(name=name, acc_slow_g=slow, label=first.label, **cat)


def _reach(src: np.ndarray, dst: np.ndarray, n: int, start: int) -> np.ndarray:
    """Nodes reachable from `start` by breadth-first search (an independent check of the SCC)."""
    out = [[] for _ in range(n)]
    for s, d in zip(src, dst):
        out[s].append(d)
    seen = np.zeros(n, dtype=bool)
    seen[start] = True
    todo = [start]
    while todo:
        for m in out[todo.pop()]:
            if not seen[m]:
                seen[m] = True
                todo.append(m)
    return seen


def _trap_clips():
    """a, b: the same gait (b a rigid copy); c: that gait for 45 frames, then a faster, longer-period gait that
    links only to itself. A path entering c's second part loops there for ever: a loop trap of 60 frames."""
    a = gait_clip("a", n_frames=60, seed=1)
    b = rigid_copy(a, "b", angle_rad=0.7, shift_xz=(3.0, 1.0))
    fast = gait_clip("fast", n_frames=60, period=21, speed=0.09, seed=3)
    return [a, b, _concat("c", gait_clip("c1", n_frames=45, seed=2), fast)]


def test_loop_trap_exists_without_the_component_step():
    clips = _trap_clips()
    g = build_from_clips(clips, GraphConfig(window_frames=5, transition_threshold_m=0.05))
    trap = (g.node_clip == 2) & (g.node_frame >= 45)
    inside = largest_component(g.edge_src, g.edge_dst, g.n_nodes)
    assert not inside[trap].any()
    # the trap is entered (an edge from c's first part leads in) and has loops inside, but never leaves
    assert np.any(~trap[g.edge_src] & trap[g.edge_dst])
    assert np.any(trap[g.edge_src] & trap[g.edge_dst] & (g.edge_kind == EDGE_TRANSITION))
    assert not np.any(trap[g.edge_src] & ~trap[g.edge_dst])


def test_component_step_prunes_the_trap_and_every_node_reaches_every_other():
    clips = _trap_clips()
    cfg = GraphConfig(window_frames=5, transition_threshold_m=0.05, connect=True, connect_thresholds_m=[])
    full = build_from_clips(clips, GraphConfig(window_frames=5, transition_threshold_m=0.05))
    g = build_from_clips(clips, cfg)
    # every kept node reaches, and is reached from, every other (BFS both ways from one node)
    fwd = _reach(g.edge_src, g.edge_dst, g.n_nodes, 0)
    bwd = _reach(g.edge_dst, g.edge_src, g.n_nodes, 0)
    assert fwd.all() and bwd.all()
    assert not np.any((g.node_clip == 2) & (g.node_frame >= 45))  # the trap is gone
    # exactly the nodes of the full graph's component through a's first node are kept
    start = int(np.flatnonzero((full.node_clip == 0) & (full.node_frame == 20))[0])
    expected = _reach(full.edge_src, full.edge_dst, full.n_nodes, start) & \
        _reach(full.edge_dst, full.edge_src, full.n_nodes, start)
    assert g.n_nodes == expected.sum()
    rep = g.build_report["component"]
    assert rep["pruned_nodes"] == full.n_nodes - expected.sum() >= 60
    assert rep["clips_kept"] == 3 and rep["relaxed_transitions"] == 0


def test_relaxed_transitions_connect_only_frames_outside_the_component():
    clips = _trap_clips()
    strict = GraphConfig(window_frames=5, transition_threshold_m=0.05)
    relaxed = GraphConfig(window_frames=5, transition_threshold_m=0.05, connect=True,
                          connect_thresholds_m=[0.5], min_component_share=0.99)
    g0 = build_from_clips(clips, strict)
    g = build_from_clips(clips, relaxed)
    rep = g.build_report["component"]
    assert rep["share_before"] < 0.9 and rep["share_connected"] > rep["share_before"]
    assert rep["relaxed_transitions"] > 0
    # the trap is now left: nodes of c's second part survive pruning and reach a
    trap = (g.node_clip == 2) & (g.node_frame >= 45)
    assert trap.sum() > 30
    # transitions among a and b (inside the component from the start) are strict ones, except relaxed ones that
    # enter a clip's head or leave its tail -- frames that were outside the component (pruning drops strict ones
    # from the clips' dead-end tails)
    ab = lambda gr: {(int(gr.node_clip[s]), float(gr.node_frame[s]), int(gr.node_clip[d]), float(gr.node_frame[d]))
                     for s, d, k in zip(gr.edge_src, gr.edge_dst, gr.edge_kind)
                     if k == EDGE_TRANSITION and gr.node_clip[s] < 2 and gr.node_clip[d] < 2}
    inside0 = largest_component(g0.edge_src, g0.edge_dst, g0.n_nodes)
    key0 = {(int(c), float(f)): bool(i) for c, f, i in zip(g0.node_clip, g0.node_frame, inside0)}
    added = ab(g) - ab(g0)
    assert len(ab(g) & ab(g0)) > 10
    assert all(not key0[(cs, fs)] or not key0[(cd, fd)] for cs, fs, cd, fd in added)


def test_clip_heads_are_entered_and_tails_left():
    """Two copies of one gait (period 15, contact changes at frames 7, 15, 22, ...): strict transitions join only
    contact changes, so each clip's head (frames before 7) and tail cannot be entered or left and are pruned.
    Clip-end transitions match each clip's first and last window-fitting frame (2 and n - 3 for a 5-frame window)
    against every frame of the other clip -- frame 2 is frame 17's pose exactly (one period on) -- so each clip is
    kept from frame 2 to frame n - 4 (the tail edge leaves from n - 4 = e - 1), no more, no less."""
    a = gait_clip("a", n_frames=60, seed=1)
    b = rigid_copy(a, "b", angle_rad=0.7, shift_xz=(3.0, 1.0))
    strict = build_from_clips([a, b], GraphConfig(window_frames=5, transition_threshold_m=0.05, connect=True,
                                                  connect_thresholds_m=[]))
    ends = build_from_clips([a, b], GraphConfig(window_frames=5, transition_threshold_m=0.05, connect=True,
                                                connect_thresholds_m=[0.05], min_component_share=0.99))
    for clip in (0, 1):
        kept = lambda gr: gr.node_frame[(gr.node_clip == clip) & (gr.node_kind == 0)]
        assert kept(strict).min() >= 7 and kept(strict).max() < 56
        assert kept(ends).min() == 2 and kept(ends).max() == 56
        assert len(kept(ends)) == 55  # every frame in between
    fwd = _reach(ends.edge_src, ends.edge_dst, ends.n_nodes, 0)
    assert fwd.all() and _reach(ends.edge_dst, ends.edge_src, ends.n_nodes, 0).all()


def test_idle_frames_are_spaced_inside_long_runs_only():
    contacts = np.zeros((100, 2), dtype=bool)
    contacts[:, 0] = True
    contacts[40:48, 1] = True  # a short run (8 frames) between two long ones
    f = idle_frames(contacts, window_frames=5, spacing_frames=10)
    assert f.tolist() == [2, 12, 22, 32, 39, 48, 58, 68, 78, 88, 97]
    assert idle_frames(contacts, 5, 0).size == 0
