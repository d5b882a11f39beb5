"""Kernel-prior energy: exact recovery when all hypotheses agree, Jacobian vs central differences, weighted PCA."""
from __future__ import annotations

import numpy as np
import pytest

from engine.olng.config import EnergyConfig
from engine.olng.energy import FrameProblem, KernelEnergy, weighted_pca
from engine.olng.pose import fk_root_frame, pose_vectors

from .synthetic import RIG, SENSORS, make_clip

DT = 0.04


def _consistent_problem(clip, frame, count, cm=100.0):
    """All `count` hypotheses equal the ground-truth frame; previous outputs and control targets consistent with it."""
    q, _ = pose_vectors(clip.local_quats)
    x = fk_root_frame(RIG, q)[0].reshape(len(q), -1) * cm
    acc = (x[frame] - 2 * x[frame - 1] + x[frame - 2]) / DT**2
    vel = (x[frame] - x[frame - 1]) / DT - 0.5 * acc * DT   # so x^t + v dt + a dt^2 / 2 lands on the truth
    tips = (x[frame].reshape(-1, 3)[SENSORS.tip]).reshape(-1)
    w = np.full(count, 1.0 / count)
    rep = lambda v: np.repeat(v[None], count, axis=0)  # noqa: E731
    problem = FrameProblem(
        weights=w, pose_targets=rep(q[frame]),
        motion_targets=rep(x[frame - 1] + vel * DT + 0.5 * acc * DT**2),
        smooth_targets=rep(2 * x[frame - 1] - x[frame - 2] + acc * DT**2),
        control_targets=rep(tips), start_pose=q[frame - 1],
    )
    return problem, q[frame], x[frame]


@pytest.mark.parametrize("kernel", ["sqrt", "mahalanobis"])
def test_energy_returns_ground_truth_when_hypotheses_agree(kernel):
    clip = make_clip("walk", 1.2, 2.0)
    problem, q_true, x_true = _consistent_problem(clip, 20, count=16)
    energy = KernelEnergy(RIG, SENSORS.tip, EnergyConfig(kernel=kernel))
    q = energy.solve(problem)
    x = fk_root_frame(RIG, q[None])[0][0].reshape(-1) * 100
    assert np.abs(x - x_true).max() < 0.05  # cm
    np.testing.assert_allclose(q, q_true, atol=1e-3)


def test_energy_moves_towards_the_heavier_mode():
    """Two clusters of hypotheses: the sqrt kernel settles near the heavily weighted one, not in between."""
    clip = make_clip("walk", 1.0, 2.0)
    q, _ = pose_vectors(clip.local_quats)
    a, b = q[5], q[17]
    targets = np.vstack([np.repeat(a[None], 12, 0), np.repeat(b[None], 4, 0)])
    w = np.full(16, 1 / 16)
    problem = FrameProblem(w, targets, None, None, None, start_pose=0.5 * (a + b))
    energy = KernelEnergy(RIG, SENSORS.tip, EnergyConfig(max_iterations=200))
    result = energy.solve(problem)
    assert np.linalg.norm(result - a) < 0.25 * np.linalg.norm(result - b)


def test_jacobian_matches_central_differences():
    clip = make_clip("walk", 1.0, 2.0)
    rng = np.random.default_rng(3)
    problem, _, _ = _consistent_problem(clip, 30, count=8)
    problem.pose_targets = problem.pose_targets + rng.normal(scale=0.2, size=problem.pose_targets.shape)
    energy = KernelEnergy(RIG, SENSORS.tip)
    residuals = energy._residual_fn(problem)
    mean, basis = weighted_pca(problem.pose_targets, problem.weights, 0.99, 3)
    z = rng.normal(scale=0.1, size=basis.shape[1])
    h = 1e-5
    central = np.stack([
        (residuals((mean + basis @ (z + h * e))[None])[0] - residuals((mean + basis @ (z - h * e))[None])[0]) / (2 * h)
        for e in np.eye(len(z))
    ], axis=1)
    q0 = mean + basis @ z
    batch = np.vstack([q0, q0 + 1e-6 * basis.T])
    res = residuals(batch)
    forward = ((res[1:] - res[0]) / 1e-6).T
    np.testing.assert_allclose(forward, central, atol=2e-4 * np.abs(central).max())


def test_weighted_pca_keeps_requested_variance():
    rng = np.random.default_rng(5)
    samples = rng.normal(size=(200, 20)) * np.linspace(3, 0.01, 20)
    weights = rng.uniform(size=200)
    weights /= weights.sum()
    mean, basis = weighted_pca(samples, weights, 0.99, 3)
    centred = samples - mean
    total = weights @ (centred**2).sum(1)
    kept = weights @ ((centred @ basis) ** 2).sum(1)
    assert kept / total >= 0.99
    assert basis.shape[1] < 20
    _, one = weighted_pca(np.repeat(samples[:1], 5, 0), np.full(5, 0.2), 0.99, 3)
    assert one.shape[1] == 3


def test_majorise_minimise_reaches_the_trf_minimum():
    """The fast solver must find as low an energy as scipy's trust-region-reflective least squares."""
    clip = make_clip("walk", 1.1, 2.0)
    rng = np.random.default_rng(11)
    problem, _, _ = _consistent_problem(clip, 25, count=32)
    problem.pose_targets = problem.pose_targets + rng.normal(scale=0.15, size=problem.pose_targets.shape)
    problem.motion_targets = problem.motion_targets + rng.normal(scale=2.0, size=problem.motion_targets.shape)
    problem.weights = rng.dirichlet(np.ones(32))
    energies = {}
    for solver in ("auto", "trf"):
        energy = KernelEnergy(RIG, SENSORS.tip, EnergyConfig(solver=solver, max_iterations=50, max_nfev=200))
        q = energy.solve(problem)
        energies[solver] = energy._kernel_energy(energy._blocks(problem), problem.weights, energy.features(q[None]))
    assert energies["auto"] <= 1.02 * energies["trf"]
