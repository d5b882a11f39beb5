"""The compiled (numba) search step against the numpy reference: bit-identical paths, costs and global states."""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.config import GraphConfig
from engine.graph.graph import build_from_clips
from engine.graph.parts import EDGE_TRANSITION
from engine.graph.online import FixedLagSynthesizer
from engine.graph.viterbi import Constraint, Observations, SearchWeights, ViterbiLattice
from engine.graph.search import ViterbiSearch

from .synth import gait_clip, observe, rigid_copy, walk_path

CFG = GraphConfig(window_frames=5, transition_threshold_m=0.05, min_jump_frames=8)


@pytest.fixture(scope="module")
def case():
    a = gait_clip("a", n_frames=80, turn_rate=0.02, seed=1, label="walk")
    b = rigid_copy(a, "b", angle_rad=1.1, shift_xz=(4.0, -2.0))
    b.label = "run"
    g = build_from_clips([a, b], CFG)
    rng = np.random.default_rng(3)
    nodes, edges = walk_path(g, 2, 70, rng, prefer_kind=EDGE_TRANSITION)
    acc, ground, heading = observe(g, nodes, edges, (1.0, -2.0), 0.4)
    acc = acc + rng.normal(0, 0.6, acc.shape)
    ground = ground + rng.normal(0, 0.05, ground.shape)
    heading = heading + rng.normal(0, 0.2, heading.shape)
    ground[20:24] = np.nan  # camera gaps: the terms are skipped for those samples
    heading[40:43] = np.nan
    return g, Observations(acc, ground, heading)


def same(a, b):
    assert np.array_equal(a.nodes, b.nodes) and np.array_equal(a.edges, b.edges)
    assert a.cost == b.cost and a.broken_constraints == b.broken_constraints  # bit-identical, not just close
    assert np.array_equal(a.ground_m, b.ground_m) and np.array_equal(a.heading_rad, b.heading_rad)
    assert a.lattice_entries == b.lattice_entries


@pytest.mark.parametrize("weights", [SearchWeights(), SearchWeights(0.5, 0, 0), SearchWeights(0.7, 0.3, 2.0),
                                     SearchWeights(0, 1, 1), SearchWeights(1.0, 1.0, 0)])
@pytest.mark.parametrize("prune_every", [0, 1, 7])
def test_compiled_search_equals_numpy_reference(case, weights, prune_every):
    g, obs = case
    ref = ViterbiSearch(g, weights, prune_every, kernel="numpy").run(obs)
    same(ViterbiSearch(g, weights, prune_every, kernel="numba").run(obs), ref)


def test_compiled_search_equals_reference_with_constraints_and_late_fix(case):
    g, obs = case
    pos, head = obs.position_m.copy(), obs.heading_rad.copy()
    pos[:5] = np.nan  # take starts without a camera fix
    head[:5] = np.nan
    late = Observations(obs.acc_g, pos, head)
    cons = [Constraint(frame=30, tolerance_frames=4, node_mask=g.label_mask("run")),
            Constraint(frame=55, tolerance_frames=2, node_mask=g.label_mask("walk"))]
    for w in (SearchWeights(), SearchWeights(0.5, 0, 0)):
        ref = ViterbiSearch(g, w, 5, kernel="numpy").run(late, cons)
        res = ViterbiSearch(g, w, 5, kernel="numba").run(late, cons)
        assert ref.broken_constraints < 7  # the constraints do bite
        same(res, ref)


def test_compiled_state_equals_reference_step_by_step(case):
    """Every per-node cost and global state, after every sample (also the online path: no batched acc rows)."""
    g, obs = case
    lats = [ViterbiLattice(g, SearchWeights(0.5, 1, 1), kernel=k) for k in ("numba", "numpy")]
    for t in range(obs.n_samples):
        for lat in lats:
            lat.step(obs.acc_g[t], obs.position_m[t], float(obs.heading_rad[t]))
        a, b = lats
        assert a.cost_offset == b.cost_offset
        assert np.array_equal(a._G, b._G)
        assert all(np.array_equal(x, y) for x, y in zip(a._state, b._state))  # ground, heading, its cos/sin
        assert np.array_equal(a.columns[-1].edges, b.columns[-1].edges) if t else True


def test_compiled_fixed_lag_equals_reference(case):
    g, obs = case
    out = {}
    for k in ("numba", "numpy"):
        syn = FixedLagSynthesizer(g, lag_s=0.5, kernel=k)
        poses = [p for t in range(obs.n_samples)
                 for p in syn.push(obs.acc_g[t], obs.position_m[t], float(obs.heading_rad[t]))] + syn.flush()
        out[k] = poses
    assert [p.node for p in out["numba"]] == [p.node for p in out["numpy"]]
    assert all(np.array_equal(p.ground_m, q.ground_m) for p, q in zip(out["numba"], out["numpy"]))


def test_unknown_kernel_is_rejected(case):
    with pytest.raises(ValueError, match="kernel"):
        ViterbiLattice(case[0], kernel="cuda")
