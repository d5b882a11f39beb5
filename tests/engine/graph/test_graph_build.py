"""Motion-graph construction on synthetic clips whose transitions and metadata are known exactly."""
from __future__ import annotations

import numpy as np
import pytest

from engine.errors import MalformedFileError
from engine.graph.config import GraphConfig
from engine.graph.graph import MotionGraph, build_from_clips
from engine.graph.parts import EDGE_NATURAL, EDGE_TRANSITION
from engine.graph.transitions import contact_change_frames

from .synth import gait_clip, rigid_copy

CFG = GraphConfig(window_frames=5, transition_threshold_m=0.05, min_jump_frames=8)


def expected_transitions(clips, cfg):
    """Every pair of contact-change frames with equal contact state: the gait is periodic and the copy rigid,
    so all such windows are identical up to a ground-plane rigid motion (distance 0, all local minima)."""
    out = set()
    offsets = np.cumsum([0] + [c.n_frames for c in clips])
    cands = [(ci, f) for ci, c in enumerate(clips) for f in contact_change_frames(c.contacts, cfg.window_frames)]
    for ca, fa in cands:
        for cb, fb in cands:
            same_state = np.array_equal(clips[ca].contacts[fa], clips[cb].contacts[fb])
            too_close = ca == cb and abs(fa - fb) < cfg.min_jump_frames
            if same_state and not too_close:
                out.add((offsets[ca] + fa - 1, offsets[cb] + fb))
    return out


@pytest.fixture(scope="module")
def two_clip_graph():
    a = gait_clip("a", n_frames=60, turn_rate=0.02, seed=1)
    b = rigid_copy(a, "b", angle_rad=1.1, shift_xz=(4.0, -2.0))
    return [a, b], build_from_clips([a, b], CFG)


def test_transitions_are_exactly_the_same_state_contact_changes(two_clip_graph):
    clips, g = two_clip_graph
    tr = {(int(s), int(d)) for s, d, k in zip(g.edge_src, g.edge_dst, g.edge_kind) if k == EDGE_TRANSITION}
    assert tr == expected_transitions(clips, CFG)
    assert len(tr) > 10


def test_threshold_rejects_dissimilar_motion():
    a = gait_clip("a", n_frames=60, seed=1)
    c = gait_clip("c", n_frames=60, period=21, speed=0.09, seed=3)  # different gait: nothing similar enough
    g = build_from_clips([a, c], CFG)
    src_clip = g.node_clip[g.edge_src[g.edge_kind == EDGE_TRANSITION]]
    dst_clip = g.node_clip[g.edge_dst[g.edge_kind == EDGE_TRANSITION]]
    assert not np.any(src_clip != dst_clip)


def test_natural_edge_metadata_is_exact(two_clip_graph):
    clips, g = two_clip_graph
    nat = g.edge_kind == EDGE_NATURAL
    rows = g.edge_meta[nat]
    assert nat.sum() == sum(c.n_frames - 1 for c in clips)
    assert np.allclose(g.meta_dheading_rad[rows], 0.02)
    # each step moves `speed` along the arrival frame's heading, i.e. turned by turn_rate in the source frame,
    # whatever the world heading of the (rotated) copy
    assert np.allclose(g.meta_dpos_m[rows], [0.04 * np.sin(0.02), 0.04 * np.cos(0.02)], atol=1e-12)
    assert np.array_equal(g.meta_acc_g[rows], np.concatenate([c.acc_g[1:] for c in clips]).astype(np.float32))


def test_edges_sorted_by_destination_and_unique(two_clip_graph):
    _, g = two_clip_graph
    key = g.edge_dst.astype(np.int64) * g.n_nodes + g.edge_src
    assert np.all(np.diff(key) > 0)
    nodes, starts = g.segments()
    assert np.array_equal(g.edge_dst[starts], nodes)
    assert g.edge_index(g.edge_src[7:9], g.edge_dst[7:9]).tolist() == [7, 8]


def test_save_load_roundtrip(tmp_path, two_clip_graph):
    _, g = two_clip_graph
    path = tmp_path / "g.npz"
    g.save(path)
    h = MotionGraph.load(path)
    assert h.config == g.config and h.clip_names == g.clip_names
    for name in ("edge_src", "edge_dst", "edge_meta", "meta_acc_g", "node_positions_m", "node_contacts"):
        assert np.array_equal(getattr(h, name), getattr(g, name))


def test_load_rejects_non_graph_files(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip at all")
    with pytest.raises(MalformedFileError, match="bad.npz"):
        MotionGraph.load(bad)
    other = tmp_path / "other.npz"
    np.savez(other, x=np.zeros(3))
    with pytest.raises(MalformedFileError, match="header_json"):
        MotionGraph.load(other)


def test_without_clips_removes_everything_derived_and_keeps_the_rest(two_clip_graph):
    clips, g = two_clip_graph
    h = g.without_clips([1])
    assert h.n_nodes == clips[0].n_frames and np.all(h.node_clip == 0)
    # surviving edges are exactly the old edges between clip-0 nodes, in (frame, frame) terms
    old = {(int(g.node_frame[s]), int(g.node_frame[d])) for s, d in zip(g.edge_src, g.edge_dst)
           if g.node_clip[s] == 0 and g.node_clip[d] == 0}
    new = {(int(h.node_frame[s]), int(h.node_frame[d])) for s, d in zip(h.edge_src, h.edge_dst)}
    assert new == old
    assert np.array_equal(h.meta_acc_g[h.edge_meta], g.meta_acc_g[g.edge_meta][
        (g.node_clip[g.edge_src] == 0) & (g.node_clip[g.edge_dst] == 0)])


def test_row_blocks_do_not_change_the_transitions(sample_clipdata):
    """Real CMU clips: the memory-bounded row-block evaluation finds exactly the one-block transitions."""
    from engine.graph.transitions import find_transitions

    clips, _ = sample_clipdata
    jw = np.ones(clips[0].positions_m.shape[1])
    whole = find_transitions(clips, 9, jw, 0.08, 8, block_rows=100_000)
    blocks = find_transitions(clips, 9, jw, 0.08, 8, block_rows=7)
    assert len(whole.src_frame) > 20
    key = lambda t: sorted(zip(t.src_frame.tolist(), t.dst_frame.tolist()))  # noqa: E731
    assert key(whole) == key(blocks)


def test_transition_cap_keeps_the_closest_per_frame(sample_clipdata):
    from engine.graph.transitions import find_transitions

    clips, _ = sample_clipdata
    jw = np.ones(clips[0].positions_m.shape[1])
    full = find_transitions(clips, 9, jw, 0.12, 8)
    capped = find_transitions(clips, 9, jw, 0.12, 8, max_per_frame=2, block_rows=5)
    counts = np.bincount(full.src_frame)
    assert counts.max() > 2  # the cap matters on this data
    assert np.bincount(capped.src_frame).max() <= 2
    for src in np.unique(full.src_frame):
        want = np.sort(full.distance_m[full.src_frame == src])[:2]
        assert np.allclose(np.sort(capped.distance_m[capped.src_frame == src]), want)


def test_load_rejects_inconsistent_arrays(tmp_path, two_clip_graph):
    _, g = two_clip_graph
    path = tmp_path / "g.npz"
    g.save(path)
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["edge_dst"] = arrays["edge_dst"].copy()
    arrays["edge_dst"][5] = g.n_nodes + 3
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(MalformedFileError, match="bad.npz.*outside the node range"):
        MotionGraph.load(tmp_path / "bad.npz")
