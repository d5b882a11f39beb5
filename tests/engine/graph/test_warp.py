"""Root warping (engine/graph/warp.py): the pose from the graph, the path from the camera.

Known answers on a graph of straight walks asked to follow a turning camera track it cannot produce: with a full
pull (gain 1, no bound) the root is the camera's exactly; with heading gain g the lag behind a constant turn of w
per sample settles at exactly w (1 - g) / g (the complementary filter's steady state); numba = numpy bit for bit.
"""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.config import GraphConfig
from engine.graph.geometry import wrap_angle
from engine.graph.graph import build_from_clips
from engine.graph.parts import EDGE_TRANSITION
from engine.graph.online import FixedLagSynthesizer
from engine.graph.viterbi import Observations, SearchWeights, ViterbiLattice
from engine.graph.search import ViterbiSearch
from engine.graph.warp import RootWarp, warp_one

from .synth import gait_clip, observe, rigid_copy, walk_path

CFG = GraphConfig(window_frames=5, transition_threshold_m=0.05, min_jump_frames=8, connect=True,
                  connect_thresholds_m=[])  # one strongly connected component: a random walk never dead-ends
TURN = 0.05  # rad per sample (86 deg/s at 30 Hz): no clip of the graph turns at all


@pytest.fixture(scope="module")
def straight():
    """Straight walks only; a path through them, observed exactly, then the camera's track of the same walk
    turning at TURN per sample (what the database lacks)."""
    a = gait_clip("a", n_frames=90, seed=1)
    b = rigid_copy(a, "b", angle_rad=0.4, shift_xz=(3.0, 1.0))
    g = build_from_clips([a, b], CFG)
    nodes, edges = walk_path(g, 1, 80, np.random.default_rng(5), prefer_kind=EDGE_TRANSITION)
    acc, _, _ = observe(g, nodes, edges, (0.0, 0.0), 0.0)
    heading = TURN * np.arange(80)
    step = 0.04 * np.stack([np.sin(heading), np.cos(heading)], axis=1)  # the gait's speed along the turn
    ground = np.concatenate([[np.zeros(2)], np.cumsum(step[1:], axis=0)])
    return g, acc, ground, heading


def _errors(res, ground, heading):
    return (np.linalg.norm(res.ground_m - ground, axis=1),
            np.abs(wrap_angle(res.heading_rad - heading)))


def test_without_warp_the_turn_is_lost(straight):
    g, acc, ground, heading = straight
    res = ViterbiSearch(g, SearchWeights(0.5, 1, 1)).run(Observations(acc, ground, heading))
    pos_err, head_err = _errors(res, ground, heading)
    assert head_err[-1] > 2.0 and pos_err[-1] > 0.5  # the graph cannot turn: metres and radians off


def test_full_warp_follows_the_camera_exactly(straight):
    g, acc, ground, heading = straight
    warp = RootWarp(1.0, 1.0, 1e3, 1e3)
    for w in (SearchWeights(0.5, 1, 1), SearchWeights(0.5, 0, 0)):  # with per-path state, and Markov + replay
        res = ViterbiSearch(g, w, warp=warp).run(Observations(acc, ground, heading))
        pos_err, head_err = _errors(res, ground, heading)
        assert pos_err.max() < 1e-9 and head_err.max() < 1e-9
        assert np.array_equal(res.nodes, ViterbiSearch(g, SearchWeights(0.5, 0, 0)).run(
            Observations(acc, None, None)).nodes) or w.position  # Markov: the poses are the accelerometers' own


def test_heading_lag_settles_at_the_complementary_filter_steady_state(straight):
    g, acc, ground, heading = straight
    gain = 0.4
    res = ViterbiSearch(g, SearchWeights(0.5, 0, 0), warp=RootWarp(0.0, gain, 0.0, 1e3)).run(
        Observations(acc, ground, heading))
    lag = wrap_angle(heading - res.heading_rad)
    assert lag[-1] == pytest.approx(TURN * (1 - gain) / gain, abs=1e-9)
    # the carried state of the search (float32) agrees with the replayed output (float64)
    lat = ViterbiLattice(g, SearchWeights(0.5, 0, 1), warp=RootWarp(0.0, gain, 0.0, 1e3))
    for t in range(len(acc)):
        lat.step(acc[t], ground[t], heading[t])
    best = lat.best_node()
    assert wrap_angle(float(lat._state[2][best]) - (heading[-1] - TURN * (1 - gain) / gain)) == pytest.approx(
        0.0, abs=1e-4)


def test_bounded_turn_per_sample(straight):
    """A correction never exceeds max_turn_rps / fps per sample: a camera heading flipped by 180 deg is followed
    at the bounded rate, not in one jump."""
    g, acc, ground, heading = straight
    flipped = heading.copy()
    flipped[40:] += np.pi
    res = ViterbiSearch(g, SearchWeights(0.5, 0, 0), warp=RootWarp(0.0, 1.0, 0.0, 3.0)).run(
        Observations(acc, ground, flipped))
    turn = np.abs(wrap_angle(np.diff(res.heading_rad)))
    assert turn.max() == pytest.approx(3.0 / 30.0, abs=1e-9)  # the graph adds no turn of its own here


def test_accelerometers_never_make_the_warped_root_worse_than_camera_only(straight):
    g, acc, ground, heading = straight
    rng = np.random.default_rng(7)
    cam_g = ground + rng.normal(0, 0.05, ground.shape)
    cam_h = heading + rng.normal(0, np.radians(10), heading.shape)
    noisy_acc = acc + rng.normal(0, 0.5, acc.shape)
    warp = RootWarp()
    cam_only = ViterbiSearch(g, SearchWeights(0, 1, 1), warp=warp).run(Observations(None, cam_g, cam_h))
    both = ViterbiSearch(g, SearchWeights(0.5, 1, 1), warp=warp).run(Observations(noisy_acc, cam_g, cam_h))
    (p0, h0), (p1, h1) = _errors(cam_only, ground, heading), _errors(both, ground, heading)
    assert p1.mean() <= p0.mean() + 1e-3 and h1.mean() <= h0.mean() + 1e-3
    assert p1.mean() < 0.05 and np.degrees(h1.mean()) < 10  # and both follow the turn


def test_warp_numba_equals_numpy_and_fixed_lag_equals_batch(straight):
    g, acc, ground, heading = straight
    cam_g = ground + np.random.default_rng(1).normal(0, 0.05, ground.shape)
    cam_g[30:35] = np.nan
    obs = Observations(acc, cam_g, heading)
    for w in (SearchWeights(0.5, 1, 1), SearchWeights(0.5, 0, 0)):
        ref = ViterbiSearch(g, w, 7, kernel="numpy", warp=RootWarp()).run(obs)
        res = ViterbiSearch(g, w, 7, kernel="numba", warp=RootWarp()).run(obs)
        assert np.array_equal(ref.nodes, res.nodes) and ref.cost == res.cost
        assert np.array_equal(ref.ground_m, res.ground_m) and np.array_equal(ref.heading_rad, res.heading_rad)
        syn = FixedLagSynthesizer(g, 10.0, w, warp=RootWarp())
        poses = [p for t in range(len(acc)) for p in syn.push(acc[t], cam_g[t], heading[t])] + syn.flush()
        assert np.array_equal([p.node for p in poses], res.nodes)
        assert np.allclose([p.ground_m for p in poses], res.ground_m, atol=1e-12)
        short = FixedLagSynthesizer(g, 0.3, w, warp=RootWarp())
        poses = [p for t in range(len(acc)) for p in short.push(acc[t], cam_g[t], heading[t])] + short.flush()
        track = np.array([p.ground_m for p in poses])
        assert len(poses) == len(acc) and np.nanmax(np.linalg.norm(track - ground, axis=1)) < 0.15


def test_warp_one_matches_the_rule():
    g, h = warp_one(0j, 0.0, 1 + 0j, 1.0, RootWarp(0.5, 0.5, 30.0 * 0.2, 30.0 * 0.1), 30.0)
    assert g == pytest.approx(0.2) and h == pytest.approx(0.1)  # both corrections hit their bound
    g, h = warp_one(0j, 0.0, 0.1j, -0.1, RootWarp(0.5, 0.5, 30.0, 30.0), 30.0)
    assert g == pytest.approx(0.05j) and h == pytest.approx(-0.05)
