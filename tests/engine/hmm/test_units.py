"""Seed 004 building blocks against exact answers (spec B5 unit tests 1-7)."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import sparse

from engine.hmm.config import HMMConfig
from engine.hmm.dtw import dtw, register
from engine.hmm.forward import chain_forward, forward
from engine.hmm.model import PhaseModel, conditional_mean, gaussian_gain, transition_matrix
from engine.hmm.phases import PHASES, GaitEvents, label_phases, segments_from_labels


def _random_hmm(rng, states=5, steps=6):
    a = rng.uniform(size=(states, states))
    a /= a.sum(axis=1, keepdims=True)
    pi = rng.dirichlet(np.ones(states))
    log_b = np.log(rng.uniform(0.05, 1.0, size=(steps, states)))
    return a, pi, log_b


def test_scaled_forward_equals_brute_force_enumeration():
    rng = np.random.default_rng(0)
    a, pi, log_b = _random_hmm(rng)
    b = np.exp(log_b)
    total = 0.0
    final = np.zeros(len(pi))
    for path in itertools.product(range(len(pi)), repeat=len(b)):
        p = pi[path[0]] * b[0, path[0]]
        for t in range(1, len(b)):
            p *= a[path[t - 1], path[t]] * b[t, path[t]]
        total += p
        final[path[-1]] += p
    alpha, loglik = forward(log_b, sparse.csr_matrix(a), pi)
    assert loglik == pytest.approx(np.log(total), abs=1e-8)
    np.testing.assert_allclose(alpha, final / total, atol=1e-12)
    assert alpha.sum() == pytest.approx(1.0)


def test_forward_does_not_underflow_over_ten_thousand_steps():
    rng = np.random.default_rng(1)
    a, pi, _ = _random_hmm(rng)
    log_b = np.log(rng.uniform(1e-3, 1e-2, size=(10_000, 5)))
    alpha, loglik = forward(log_b, sparse.csr_matrix(a), pi)
    assert np.isfinite(loglik) and loglik < -40_000
    assert alpha.sum() == pytest.approx(1.0)


def test_gaussian_gain_matches_the_true_regression():
    rng = np.random.default_rng(2)
    dx, dy = 3, 4
    m = rng.normal(size=(dx + dy, dx + dy))
    cov = m @ m.T + np.eye(dx + dy)
    z = rng.multivariate_normal(np.zeros(dx + dy), cov, size=100_000)
    body, imu = z[None, :, :dx].swapaxes(0, 1), z[None, :, dx:].swapaxes(0, 1)   # H = 1e5 samples, L = 1
    gain = gaussian_gain(body, imu, ridge=0.0, floor=0.0)[0]
    true = cov[:dx, dx:] @ np.linalg.inv(cov[dx:, dx:])
    np.testing.assert_allclose(gain, true, atol=0.03)
    y = rng.normal(size=dy)
    np.testing.assert_allclose(conditional_mean(np.zeros((1, dx)), np.zeros((1, dy)), gain[None], y)[0], true @ y, atol=0.1)
    assert np.all(gaussian_gain(body[:1], imu[:1], 1e-2, 1e-3) == 0)  # one example: no covariance, template only


def _phase(behaviour, phase, length):
    return PhaseModel(behaviour, phase, np.zeros((1, length, 1)), np.zeros((1, length, 1)), np.zeros((length, 1)),
                      np.zeros((length, 1)), np.zeros((length, 1, 1)))


def test_transitions_rows_sum_to_one_no_backward_moves_and_thirds_at_chain_end():
    phases = [_phase("walk", 0, 4), _phase("walk", 1, 3), _phase("run", 0, 5), _phase("run", 4, 2)]
    offsets = np.r_[0, np.cumsum([p.length for p in phases])]
    a = transition_matrix(phases, offsets, HMMConfig()).toarray()
    np.testing.assert_allclose(a.sum(axis=1), 1.0)
    for h, p in enumerate(phases):
        for i in range(p.length):
            src = offsets[h] + i
            inside = a[src, offsets[h]: offsets[h + 1]]
            if i > 0:
                assert np.all(inside[1:i] == 0)        # no backward move except chain-start re-entry from the end
    last = offsets[1] - 1          # walk-IC's final frame: self stays, next + skip (2/3) run past the chain end
    assert a[last, last] == pytest.approx(1 / 3)
    assert a[last, offsets[0]] == pytest.approx(2 / 9)           # upper self: back to the phase start
    assert a[last, offsets[1]] == pytest.approx(2 / 9)           # upper next: the next phase of the same behaviour
    assert a[last, offsets[2]] + a[last, offsets[3]] == pytest.approx(2 / 9)  # exit: spread over the other behaviour
    second_last = offsets[1] - 2
    assert a[second_last, offsets[1]] > 0               # the skip from L-2 reaches the exit


def test_progress_tracking_follows_time_scaled_input():
    """A 60-frame 6-D sinusoid template; the expected state tracks the query's true index within 2 frames up
    to 2x speed (the skip transition's limit) and lags beyond it."""
    t = np.arange(60)
    template = np.stack([np.sin(2 * np.pi * (k + 1) * t / 90 + k) for k in range(6)], axis=1)  # not periodic in 60
    phases = [PhaseModel("x", 0, template[None], template[None], template, template, np.zeros((60, 6, 6)))]
    a = transition_matrix(phases, np.array([0, 60]), HMMConfig())
    rng = np.random.default_rng(3)
    errors = {}
    for speed in (0.6, 1.0, 1.5, 1.9, 3.0):
        true = np.arange(0, 58, speed)
        query = np.stack([np.interp(true, t, template[:, k]) for k in range(6)], axis=1) + rng.normal(0, 0.05, (len(true), 6))
        alpha = np.eye(60)[0]
        worst = 0.0
        for i, y in enumerate(query):
            log_b = -0.5 * ((template - y) ** 2).sum(axis=1) / 0.2**2   # sigma = 0.2, the sharp end of B6.2's sweep
            alpha, _ = forward(log_b[None], a, alpha if i == 0 else a.T @ alpha)
            worst = max(worst, abs(alpha @ t - true[i]))
        errors[speed] = worst
    assert all(errors[s] <= 2.0 for s in (0.6, 1.0, 1.5, 1.9)), errors
    assert errors[3.0] > 2.0


def test_chain_forward_matches_the_generic_forward():
    rng = np.random.default_rng(4)
    log_b = np.log(rng.uniform(0.1, 1, size=(7, 3, 5)))
    cfg = HMMConfig()
    alpha, loglik = chain_forward(log_b, cfg.p_self, cfg.p_next, cfg.p_skip)
    a = np.zeros((5, 5))
    for i in range(5):
        for step, p in ((0, cfg.p_self), (1, cfg.p_next), (2, cfg.p_skip)):
            a[i, min(i + step, 4)] += p
    for c in range(3):
        ref_alpha, ref_ll = forward(log_b[:, c], sparse.csr_matrix(a), np.full(5, 0.2))
        np.testing.assert_allclose(alpha[c], ref_alpha, atol=1e-12)
        assert loglik[c] == pytest.approx(ref_ll)


def test_segmentation_produces_the_eight_phases_in_order():
    """One gait cycle written as Table 1's conditions, each held for 3 frames; a second cycle follows."""
    rows = [  # RH RT LH LT RCE LCE, one row satisfying each phase's start condition (and not the next one's)
        (1, 0, 0, 1, 0, 0), (1, 1, 0, 0, 0, 0), (1, 1, 1, 0, 0, 1), (0, 1, 0, 0, 0, 0),
        (0, 1, 1, 0, 0, 0), (0, 0, 1, 1, 0, 0), (0, 0, 1, 1, 1, 0), (0, 0, 0, 1, 0, 0),
    ]
    held = []
    for k, r in enumerate(rows):
        later = r if k != 6 else (0, 0, 1, 0, 0, 0)   # MSW's later frames must not already satisfy TSW's start
        held += [r, later, later]
    stream = np.array(held * 2, bool)
    stream[:, 4:] &= np.tile([True, False, False], 16)[:, None]   # crossings are single-frame events
    events = GaitEvents(*[stream[:, k] for k in range(6)])
    labels = label_phases(events)
    np.testing.assert_array_equal(labels, np.repeat(np.tile(np.arange(8), 2), 3))
    segments = segments_from_labels(labels, max_frames=12, min_frames=2)
    assert [s.phase for s in segments] == list(range(8)) * 2
    assert all(a.stop == b.start for a, b in zip(segments[:-1], segments[1:]))
    long = segments_from_labels(np.zeros(30, int), max_frames=12, min_frames=2)
    assert [s.stop - s.start for s in long] == [10, 10, 10] and len(PHASES) == 8


def test_dtw_registration_undoes_a_time_stretch_and_carries_the_paired_signal():
    ref_t = np.linspace(0, 1, 20)
    reference = np.stack([np.sin(2 * np.pi * ref_t), np.cos(3 * ref_t)], axis=1)
    stretched_t = np.linspace(0, 1, 33) ** 1.3
    stretched = np.stack([np.sin(2 * np.pi * stretched_t), np.cos(3 * stretched_t)], axis=1)
    paired = np.stack([stretched_t], axis=1)               # e.g. the IMU stream recorded with it
    cost, path = dtw(stretched, reference)
    back = register(stretched, path, len(reference))
    assert np.abs(back - reference).max() < 0.15
    assert np.abs(register(paired, path, len(reference))[:, 0] - ref_t).max() < 0.06
    same_cost, same_path = dtw(reference, reference)
    assert same_cost == 0.0 and np.array_equal(same_path, np.stack([np.arange(20)] * 2, axis=1))
    brute = np.full((34, 21), np.inf)
    brute[0, 0] = 0.0
    local = np.linalg.norm(stretched[:, None] - reference[None], axis=2)
    for i in range(1, 34):
        for j in range(1, 21):
            brute[i, j] = local[i - 1, j - 1] + min(brute[i - 1, j - 1], brute[i - 1, j], brute[i, j - 1])
    assert cost == pytest.approx(brute[-1, -1])
