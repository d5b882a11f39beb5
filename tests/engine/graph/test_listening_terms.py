"""The accelerometer-only search's optional listening terms (issue 18 item 3) on the shipped CMU clips: per-sensor
weights (engine/graph/sensor_weights.py) and tilt from low-passed accelerations (engine/graph/gravity_term.py),
against answers known by construction."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from engine.graph.config import GraphConfig
from engine.graph.graph import MotionGraph
from engine.graph.gravity_term import GravityTerm, ema_weight, unit
from engine.graph.online import FixedLagSynthesizer
from engine.graph.parts import NODE_ORIGINAL
from engine.graph.search import ViterbiSearch
from engine.graph.sensor_weights import sensor_weights
from engine.graph.viterbi import Observations, SearchWeights, ViterbiLattice
from engine.mocap import standard_placements, virtual_accelerometers

BASE = SearchWeights(1.0, 0.0, 0.0, forgetting=0.9, decision_frames=6, blend_paths=4)


@pytest.fixture(scope="module")
def graph(sample_motions):
    return MotionGraph.build(sample_motions, standard_placements(sample_motions[0].skeleton), GraphConfig())


@pytest.fixture(scope="module")
def acc(sample_motions):
    motion = sample_motions[0]
    noisy = virtual_accelerometers(motion, standard_placements(motion.skeleton))
    return noisy + np.random.default_rng(1).normal(0.0, 0.2, noisy.shape)


def test_weighted_rows_are_the_weighted_squared_distance(graph, acc):
    """C_A with weights w_s = acc weight / S x sum_s w_s ||a_s - m_s||^2, computed here directly."""
    power = -2.0
    lat = ViterbiLattice(graph, replace(BASE, sensor_weighting=power), kernel="numpy")
    w = sensor_weights(graph, list(range(6)), power)
    assert np.isclose(w.mean(), 1.0) and w.std() > 0.01
    meta = np.asarray(graph.meta_acc_g, float)
    want = (w * ((acc[5][None] - meta) ** 2).sum(axis=2)).sum(axis=1) / 6
    assert np.allclose(lat.acc_rows_batch(acc[5:6])[0], want, rtol=1e-4, atol=1e-4)


def test_gravity_database_rows_are_the_low_passed_clip(graph, acc, sample_motions):
    """Clip 0's original nodes carry its clean accelerations low-passed causally along the clip, normalised."""
    term = GravityTerm(graph, list(range(6)), 1.0)
    motion = sample_motions[0]
    clean = virtual_accelerometers(motion, standard_placements(motion.skeleton))
    nodes = np.flatnonzero((graph.node_clip == 0) & (graph.node_kind == NODE_ORIGINAL))
    nodes = nodes[np.argsort(graph.node_frame[nodes])]
    frames = graph.node_frame[nodes].astype(int)
    alpha = ema_weight(graph.config.fps, 0.5)
    mean, want = clean[frames[0]].copy(), []
    for f in frames:
        mean += alpha * (clean[f] - mean)
        want.append(unit(mean).reshape(-1))
    rows = term.meta_rows_t[:, graph.node_arrival[nodes]].T / term.scale
    assert np.allclose(rows, want, atol=2e-3)


@pytest.mark.parametrize("kernel", ["numba", "numpy"])
@pytest.mark.parametrize("option", [dict(gravity=1.0), dict(sensor_weighting=-4.0)])
def test_batch_equals_fixed_lag(graph, acc, kernel, option):
    weights = replace(BASE, **option)
    batch = ViterbiSearch(graph, weights, kernel=kernel).run(Observations(acc))
    syn = FixedLagSynthesizer(graph, 2.0, weights, kernel=kernel, confidence_reference=1.0)
    out = []
    for t in range(len(acc)):
        out += syn.push(acc[t])
    out += syn.flush()
    assert np.array_equal([p.node for p in out], batch.nodes)
    assert np.array_equal(np.stack([p.blend_nodes for p in out]), batch.blend_nodes)
    plain = ViterbiSearch(graph, BASE, kernel=kernel).run(Observations(acc))
    assert plain.cost != batch.cost  # the option changes the search


def test_the_live_preset_weighs_sensors_and_leaves_the_gravity_term_off():
    w = SearchWeights.camera_following()
    assert w.gravity == 0.0 and w.sensor_weighting == -4.0
    assert SearchWeights(1.0, 0.0, 0.0).sensor_weighting == 0.0  # seed 000's search: every sensor alike


def test_a_graph_without_joint_rotations_weighs_every_sensor_alike(graph):
    """A graph built from bare clip arrays has no poses to compare: the preset's weighting is skipped, so the
    lattice equals the unweighted one (not an error: such graphs search on accelerations alone)."""
    bare = replace(graph, node_rotations=None)
    weighted = ViterbiLattice(bare, replace(BASE, sensor_weighting=-4.0), kernel="numpy")
    plain = ViterbiLattice(bare, BASE, kernel="numpy")
    assert weighted._acc_scale is None
    assert np.array_equal(weighted._meta_acc_t, plain._meta_acc_t)


def test_flags_set_the_weights_and_reject_bad_values():
    import argparse

    from engine.errors import CourtsideError
    from engine.graph.cli import add_search_args, weights_from_args
    from engine.graph.warp import RootWarp

    p = argparse.ArgumentParser()
    add_search_args(p)
    got = weights_from_args(p.parse_args(["--gravity-weight", "0.3", "--sensor-weighting=-4"]), RootWarp())
    assert (got.gravity, got.sensor_weighting) == (0.3, -4.0)
    with pytest.raises(CourtsideError, match="--sensor-weighting"):
        weights_from_args(p.parse_args(["--sensor-weighting", "nan"]), RootWarp())
    with pytest.raises(CourtsideError, match="--gravity-weight"):
        weights_from_args(p.parse_args(["--gravity-weight=-1"]), RootWarp())
