"""Root fusion (engine/graph/root_fusion.py): the output root from the camera, the pose from the database.

Known answers: the smoother's estimate of a frame, decided `lag` frames later, equals the least-squares (MAP)
solution of the constant-velocity model over every fix up to then, solved independently here as one dense linear
system (batch: over the whole take); on a synthetic graph asked to follow a turn it lacks, the output root of the
batch search and of the fixed-lag decoder is the same whatever the accelerometers say (bit for bit, and equal to
the smoother of the fixes), where the warped root without fusion changes with them; a camera dropout is bridged by
the path's own steps exactly and the track is rejoined at exactly max_speed / fps per frame.
"""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.config import GraphConfig
from engine.graph.geometry import wrap_angle
from engine.graph.graph import build_from_clips
from engine.graph.parts import EDGE_TRANSITION
from engine.graph.online import FixedLagSynthesizer
from engine.graph.root_fusion import RootFuser, RootFusion, fuse_track
from engine.graph.viterbi import Observations, SearchWeights
from engine.graph.search import ViterbiSearch
from engine.graph.warp import RootWarp

from .synth import gait_clip, observe, rigid_copy, walk_path

FPS = 30.0
CFG = GraphConfig(window_frames=5, transition_threshold_m=0.05, min_jump_frames=8, connect=True,
                  connect_thresholds_m=[])
TURN = 0.05  # rad per sample: no clip of the graph turns


def _least_squares(z: np.ndarray, process: float, noise_sd: float, n: int) -> np.ndarray:
    """MAP values (n,) of a constant-velocity track given fixes z (n,) (NaN = none; z[0] given): the dense normal
    equations of  sum (p_t - z_t)^2 / R + v_0^2 / 1e4 + sum e_t^T Q^-1 e_t,  e_t = x_t+1 - F x_t."""
    dt = 1.0 / FPS
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Qi = np.linalg.inv(process * np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]]))
    A = np.zeros((2 * n, 2 * n))
    b = np.zeros(2 * n)
    for t in range(n):
        if np.isfinite(z[t]):
            A[2 * t, 2 * t] += 1 / noise_sd ** 2
            b[2 * t] += z[t] / noise_sd ** 2
    A[1, 1] += 1e-4
    for t in range(n - 1):
        D = np.zeros((2, 2 * n))  # e_t = D x
        D[:, 2 * t + 2:2 * t + 4] = np.eye(2)
        D[:, 2 * t:2 * t + 2] = -F
        A += D.T @ Qi @ D
    return np.linalg.solve(A, b)[0::2]


@pytest.fixture(scope="module")
def fixes():
    """60 frames of a noisy walk (1.2 m/s, turning), with a 5-frame gap (shorter than max_gap: still covered)."""
    rng = np.random.default_rng(3)
    t = np.arange(60) / FPS
    truth = np.stack([1.2 * t, 0.3 * np.sin(2 * t)], axis=1)
    pos = truth + rng.normal(0, 0.05, truth.shape)
    head = 0.2 + 0.8 * t + rng.normal(0, 0.17, len(t))  # small angles: no wrap, so least squares applies as is
    pos[20:25], head[20:25] = np.nan, np.nan
    return pos, head


def test_batch_smoother_is_the_least_squares_track(fixes):
    pos, head = fixes
    f = RootFusion()
    ground, heading = fuse_track(f, FPS, pos, head, np.zeros_like(pos), np.zeros(len(head)))
    for k in range(2):
        assert np.allclose(ground[:, k], _least_squares(pos[:, k], f.position_process, f.position_noise_m, 60),
                           atol=1e-9, rtol=0)
    assert np.allclose(heading, _least_squares(head, f.heading_process, f.heading_noise_rad, 60), atol=1e-9, rtol=0)


@pytest.mark.parametrize("lag", [0, 7])
def test_fixed_lag_estimate_is_the_least_squares_track_up_to_the_lag(fixes, lag):
    """Frame s decided after frame s + lag is pushed: the least-squares value of s given fixes 0 .. s + lag."""
    pos, head = fixes
    f = RootFusion()
    fuser = RootFuser(f, FPS)
    out = []
    for t in range(60):
        fuser.push(pos[t], head[t])
        if t >= lag:
            out.append(fuser.decide(np.zeros((1, 2)), np.zeros(1))[0][0, 0])
    for s in (0, 10, 22, 40, 60 - lag - 1):
        n = s + lag + 1
        assert out[s] == pytest.approx(_least_squares(pos[:n, 0], f.position_process, f.position_noise_m, n)[s],
                                       abs=1e-9)


def test_heading_innovations_wrap():
    """A heading track crossing +-pi is smoothed as the continuous angle it is, not averaged through 0."""
    n = 40
    truth = np.pi - 0.3 + 0.02 * np.arange(n)  # crosses pi at frame 15
    _, heading = fuse_track(RootFusion(), FPS, np.zeros((n, 2)), wrap_angle(truth), np.zeros((n, 2)), np.zeros(n))
    assert np.abs(wrap_angle(heading - truth)).max() < 1e-3


def test_dropout_follows_the_path_then_rejoins_at_the_bounded_rate():
    """Fixes on frames 0-29 and from 90 on, 1 m to the side of the path after the gap; the path walks straight
    at 1 m/s facing +Z. Frames 30-44 are covered (within max_gap 0.5 s of the last fix), 45-89 move by the path's
    own steps exactly, and from frame 90 the offset to the smoothed track shrinks by max_speed / fps per frame."""
    n = 150
    t = np.arange(n) / FPS
    path_g = np.stack([np.zeros(n), 1.0 * t], axis=1)
    path_h = np.zeros(n)
    pos = path_g.copy()
    pos[90:, 0] += 1.0
    pos[30:90] = np.nan
    f = RootFusion(max_speed_mps=3.0)
    ground, heading = fuse_track(f, FPS, pos, path_h.copy(), path_g, path_h)
    assert np.array_equal(heading, np.zeros(n))  # the heading fixes: constant 0, smoothed exactly
    steps = np.diff(ground[44:90], axis=0)
    assert np.allclose(steps, [0.0, 1.0 / FPS], atol=1e-12)  # dead reckoning: the path's own step
    smooth, _ = fuse_track(f, FPS, pos, path_h.copy(), path_g * np.nan, path_h)  # the smoothed track alone
    gap = np.linalg.norm(ground[90:] - smooth[90:], axis=1)
    first = np.linalg.norm(ground[89] + [0.0, 1.0 / FPS] - smooth[90])  # dead-reckoned frame 90 vs the track
    expected = np.maximum(0.0, first - f.max_speed_mps / FPS * np.arange(1, n - 89))
    assert first > 0.5 and np.allclose(gap, expected, atol=1e-12)
    assert np.array_equal(ground[90 + int(np.ceil(first * FPS / 3.0)):], smooth[90 + int(np.ceil(first * FPS / 3.0)):])


def test_no_camera_at_all_is_the_path_itself():
    n = 20
    path_g = np.random.default_rng(1).normal(size=(n, 2))
    path_h = np.linspace(-1, 1, n)
    ground, heading = fuse_track(RootFusion(), FPS, None, None, path_g, path_h)
    assert np.allclose(ground, path_g, atol=1e-12) and np.allclose(heading, path_h, atol=1e-12)


@pytest.fixture(scope="module")
def turning():
    """A graph of straight walks; a path through it observed exactly, and a noisy camera following the same walk
    turning at TURN per sample (the database lacks the turn)."""
    a = gait_clip("a", n_frames=90, seed=1)
    b = rigid_copy(a, "b", angle_rad=0.4, shift_xz=(3.0, 1.0))
    g = build_from_clips([a, b], CFG)
    nodes, edges = walk_path(g, 1, 80, np.random.default_rng(5), prefer_kind=EDGE_TRANSITION)
    acc, _, _ = observe(g, nodes, edges, (0.0, 0.0), 0.0)
    heading = TURN * np.arange(80)
    step = 0.04 * np.stack([np.sin(heading), np.cos(heading)], axis=1)
    ground = np.concatenate([[np.zeros(2)], np.cumsum(step[1:], axis=0)])
    rng = np.random.default_rng(7)
    cam_g = ground + rng.normal(0, 0.05, ground.shape)
    cam_h = heading + rng.normal(0, np.radians(10), heading.shape)
    return g, acc, ground, heading, cam_g, cam_h


def _batch(g, acc, cam_g, cam_h, weights, fusion):
    res = ViterbiSearch(g, weights, warp=RootWarp()).run(Observations(acc, cam_g, cam_h))
    return (*fuse_track(fusion, FPS, cam_g, cam_h, res.ground_m, res.heading_rad), res.nodes)


def _online(g, acc, cam_g, cam_h, weights, fusion, lag_s):
    syn = FixedLagSynthesizer(g, lag_s, weights, warp=RootWarp(), fusion=fusion, confidence_reference=1.0)
    poses = []
    for t in range(len(cam_h)):
        poses += syn.push(None if acc is None else acc[t], cam_g[t], float(cam_h[t]))
    poses += syn.flush()
    return np.array([p.ground_m for p in poses]), np.array([p.heading_rad for p in poses]), poses


def test_accelerometers_cannot_change_the_fused_root(turning):
    """Camera only, the right accelerometers, or ones that read nothing the graph holds: the search picks
    different motions, the output root is the same to the bit -- the smoothed camera track -- in batch and at
    a fixed lag; without fusion (the warped path's root) the accelerometers do move it."""
    g, acc, ground, heading, cam_g, cam_h = turning
    wrong = np.random.default_rng(11).normal(0, 1, acc.shape)
    inputs = [(None, SearchWeights(0.0, 10, 3)), (acc, SearchWeights(0.5, 10, 3)), (wrong, SearchWeights(0.5, 10, 3))]
    smooth = fuse_track(RootFusion(), FPS, cam_g, cam_h, ground * np.nan, heading * np.nan)
    batch = [_batch(g, a, cam_g, cam_h, w, RootFusion()) for a, w in inputs]
    assert not np.array_equal(batch[0][2], batch[2][2])  # the poses differ ...
    for gr, hd, _ in batch:  # ... the root does not
        assert np.array_equal(gr, smooth[0]) and np.array_equal(hd, smooth[1])
    lagged = [_online(g, a, cam_g, cam_h, w, RootFusion(), 0.3) for a, w in inputs]
    for gr, hd, _ in lagged[1:]:
        assert np.array_equal(gr, lagged[0][0]) and np.array_equal(hd, lagged[0][1])
    unfused = [_batch(g, a, cam_g, cam_h, w, RootFusion.off()) for a, w in inputs]
    assert not np.array_equal(unfused[0][0], unfused[2][0])  # the old output root depends on the pick


def test_fused_root_beats_the_camera_and_places_the_pose(turning):
    g, acc, ground, heading, cam_g, cam_h = turning
    gr, hd, poses = _online(g, acc, cam_g, cam_h, SearchWeights(0.5, 10, 3), RootFusion(), 80 / FPS)
    gb, hb, _ = _batch(g, acc, cam_g, cam_h, SearchWeights(0.5, 10, 3), RootFusion())
    assert np.array_equal(gr, gb) and np.array_equal(hd, hb)  # lag >= the take: the batch answer exactly
    raw = np.linalg.norm(cam_g - ground, axis=1).mean(), np.abs(wrap_angle(cam_h - heading)).mean()
    fused = np.linalg.norm(gr - ground, axis=1).mean(), np.abs(wrap_angle(hd - heading)).mean()
    assert fused[0] < 0.6 * raw[0] and fused[1] < 0.6 * raw[1]
    root = np.array([p.joint_positions_m[0, [0, 2]] for p in poses])
    assert np.allclose(root, gr, atol=1e-9)  # the emitted joints stand on the fused root
