"""The search's edge order (EdgeRuns) and the float32 cos/sin it relies on, against exact properties."""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.config import GraphConfig
from engine.graph.edge_runs import MIN_RUN, EdgeRuns
from engine.graph.graph import build_from_clips
from engine.graph.trig32 import cos_sin

from .synth import gait_clip, rigid_copy


@pytest.fixture(scope="module")
def graph():
    a = gait_clip("a", n_frames=120, turn_rate=0.02, seed=1)
    b = rigid_copy(a, "b", angle_rad=0.7, shift_xz=(3.0, 1.0))
    return build_from_clips([a, b], GraphConfig(window_frames=5, transition_threshold_m=0.05, min_jump_frames=8,
                                                msv=True))


def test_every_edge_appears_once_and_runs_are_contiguous_diagonals(graph):
    r = EdgeRuns(graph.edge_src, graph.edge_dst, graph.edge_meta, graph.n_nodes)
    assert np.array_equal(np.sort(r.edge_id), np.arange(graph.n_edges))
    assert np.array_equal(r.src, graph.edge_src[r.edge_id]) and np.array_equal(r.dst, graph.edge_dst[r.edge_id])
    assert r.n_runs > 0 and np.all(r.run_len >= MIN_RUN)
    assert r.run_edge0[0] == 0 and r.run_edge0[-1] + r.run_len[-1] == r.n_run_edges
    for s0, d0, e0, m0, n in zip(r.run_src0, r.run_dst0, r.run_edge0, r.run_meta0, r.run_len):
        i = np.arange(n)
        assert np.array_equal(r.src[e0:e0 + n], s0 + i) and np.array_equal(r.dst[e0:e0 + n], d0 + i)
        assert np.array_equal(r.meta[e0:e0 + n], m0 + i)
    # clips, their slow-down nodes and speed-up edges are mostly runs; transitions are scattered
    assert r.n_run_edges > 0.6 * graph.n_edges
    sc = slice(r.n_run_edges, None)
    assert np.all(np.diff(r.dst[sc]) >= 0)
    assert np.array_equal(r.sc_nodes, np.unique(r.dst[sc]))
    for j, n in enumerate(r.sc_nodes):
        assert np.all(r.dst[r.sc_indptr[j]:r.sc_indptr[j + 1]] == n)


def test_rank_layers_replay_the_search_order_per_destination(graph):
    r = EdgeRuns(graph.edge_src, graph.edge_dst, graph.edge_meta, graph.n_nodes)
    seen = np.concatenate([idx for idx, _ in r.layers])
    assert np.array_equal(np.sort(seen), np.arange(graph.n_edges))
    last = np.full(graph.n_nodes, -1)
    for idx, d in r.layers:
        assert len(np.unique(d)) == len(d) and np.array_equal(d, r.dst[idx])
        assert np.all(idx > last[d])  # a destination's r-th edge comes after its (r-1)-th in search order
        last[d] = idx


def test_short_diagonals_are_scattered():
    # 0 -> 1 -> ... -> 9 (a run of 9) and 20 -> 21 -> 22 (too short), plus one jump 5 -> 20
    src = np.r_[np.arange(9), 20, 21, 5]
    dst = np.r_[np.arange(1, 10), 21, 22, 20]
    order = np.lexsort((src, dst))
    r = EdgeRuns(src[order], dst[order], np.arange(len(src)), 23)
    assert r.n_runs == 1 and r.n_run_edges == 9 and r.run_src0[0] == 0
    assert np.array_equal(np.sort(r.dst[9:]), [20, 21, 22])


def test_float32_cos_sin_is_accurate_and_identical_compiled():
    x = np.linspace(-np.pi, np.pi, 200_001).astype(np.float32)
    c, s = cos_sin(x)
    assert c.dtype == s.dtype == np.float32
    assert np.abs(c - np.cos(x.astype(float))).max() < 5e-7 and np.abs(s - np.sin(x.astype(float))).max() < 5e-7
    numba = pytest.importorskip("numba")
    compiled = numba.njit(cos_sin)
    for v in x[::997]:
        cc, ss = compiled(v)
        assert np.float32(cc) == c[np.searchsorted(x, v)] and np.float32(ss) == s[np.searchsorted(x, v)]
