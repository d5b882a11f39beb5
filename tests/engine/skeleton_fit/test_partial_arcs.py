"""Joint centres on partial arcs (issue 14): known centres where the GDKE closed form alone is biased.

A real joint sweeps a cap or an arc, not a sphere. There the closed form minimises the algebraic residual and its
bias does not shrink with N; fit_joint refines it on the geometric residual. Each bound below sits between the
refined error and the closed-form-only error, so these tests fail on the GDKE-only fit (refine_iterations=0
shows that in the same test)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from engine.skeleton_fit.frames import frame_from_three, to_local
from engine.skeleton_fit.gdke import JointFitConfig, JointType, _inverse_small, fit_joint, refine_centre, sphere_fit
from engine.skeleton_fit.score import cluster_poses, score_centre
from engine.skeleton_fit.synthetic import functional_trial, random_rotation, spherical_cap

SIGMA, RADIUS = 0.002, 0.3
GDKE_ONLY = JointFitConfig(static_std=0.0, refine_iterations=0)
REFINED = JointFitConfig(static_std=0.0)


@pytest.mark.parametrize("half_angle, n, bound_factor", [(60.0, 10000, 12.0), (30.0, 2000, 40.0)])
def test_cap_centre_within_bound_where_closed_form_is_biased(half_angle, n, bound_factor):
    """60° cap, N = 10⁴: GDKE ≈ 23·σ/√N, refined ≈ 6.6; 30° cap, N = 2000: GDKE ≈ 130, refined ≈ 21."""
    rng = np.random.default_rng(int(half_angle))
    centre = np.array([0.4, -0.1, 0.9])
    refined, closed = [], []
    for _ in range(5):
        pts = spherical_cap(rng, n, half_angle, RADIUS, SIGMA, centre)
        refined.append(np.linalg.norm(fit_joint(pts, REFINED).centre - centre))
        closed.append(np.linalg.norm(fit_joint(pts, GDKE_ONLY).centre - centre))
    bound = bound_factor * SIGMA / np.sqrt(n)
    assert np.median(refined) < bound
    assert np.median(closed) > bound  # the bias this test exists for


def test_refinement_reaches_the_geometric_least_squares_optimum():
    """Same minimum as scipy's Levenberg-Marquardt on Σ(|x − c| − R)², from the closed-form start."""
    rng = np.random.default_rng(4)
    pts = spherical_cap(rng, 500, 30.0, RADIUS, SIGMA)
    start = sphere_fit(pts).centre
    fit = refine_centre([pts], start, iterations=20, tol=1e-12, rel_tol=0.0)
    ref = least_squares(lambda p: np.linalg.norm(pts - p[:3], axis=1) - p[3],
                        np.append(start, RADIUS), method="lm", xtol=1e-15, ftol=1e-15).x[:3]
    assert np.linalg.norm(fit.centre - ref) < 1e-8
    quick = refine_centre([pts], start)  # default stop: a step below 1 % of the expected error
    assert quick.iterations <= 4
    assert np.linalg.norm(quick.centre - ref) < 0.01 * quick.expected_error


def test_full_sphere_error_stays_in_the_eq7_band_after_refinement():
    """The refinement must not spoil the full-sphere case. Spec 002 §5 test 4's protocol (N ~ U{4..1000}, σ/R in
    [1e-4, 0.05]): |c − c0|·√N/σ mean in [2.6, 3.1], std in [1.0, 1.45]. At a fixed small N the factor is larger for
    every estimator (N = 10: 3.4 for the closed form and for iterative least squares alike, spec and bench), so the
    band is a statement about the spec's mix of N, not about N = 10."""
    rng = np.random.default_rng(7)
    errors = []
    for _ in range(400):
        n = int(rng.integers(4, 1001))
        centre, sigma = rng.normal(0, 0.5, 3), RADIUS * rng.uniform(1e-4, 0.05)
        pts = spherical_cap(rng, n, 180.0, RADIUS, sigma, centre)
        errors.append(np.linalg.norm(fit_joint(pts, REFINED).centre - centre) * np.sqrt(n) / sigma)
    assert 2.6 <= np.mean(errors) <= 3.1, np.mean(errors)
    assert 1.0 <= np.std(errors) <= 1.45, np.std(errors)


def test_reported_arc_and_expected_error_match_the_data():
    rng = np.random.default_rng(9)
    for half_angle in (90.0, 60.0, 30.0):
        fits, errors = [], []
        for _ in range(20):
            pts = spherical_cap(rng, 400, half_angle, RADIUS, SIGMA)
            fit = fit_joint(pts, REFINED)
            fits.append(fit)
            errors.append(np.linalg.norm(fit.centre))
        assert abs(np.median([f.arc_deg for f in fits]) - half_angle) < 3.0
        # expected RMS error vs the observed RMS error over the trials
        ratio = np.sqrt(np.mean(np.square(errors))) / np.median([f.expected_error for f in fits])
        assert 0.6 < ratio < 1.5, (half_angle, ratio)


def test_hinge_centre_on_a_60_degree_arc():
    """A hinge sweeping ±30°: the in-plane centre error of the closed form (~1.7 mm) drops to ~0.5 mm."""
    rng = np.random.default_rng(3)
    refined, closed = [], []
    for _ in range(5):
        rot, centre = random_rotation(rng), rng.normal(0, 0.1, 3)
        angle = rng.uniform(-np.radians(30), np.radians(30), 2000)
        pts = centre + RADIUS * np.stack([np.cos(angle), np.sin(angle), 0 * angle], 1) @ rot.T
        pts += rng.normal(0, 0.001, pts.shape)
        for cfg, out in ((REFINED, refined), (GDKE_ONLY, closed)):
            fit = fit_joint(pts, cfg)
            assert fit.kind is JointType.HINGE and abs(fit.axis @ rot[:, 2]) > 0.999
            miss = fit.centre - centre
            out.append(np.linalg.norm(miss - (miss @ fit.axis) * fit.axis))
    assert np.median(refined) < 0.0009 < np.median(closed)


def _functional_cases(amplitude, noise, count, seed):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        trial = functional_trial(rng, amplitude, noise)
        parent = frame_from_three(*(trial.parent[:, i] for i in range(3)))
        truth = to_local(trial.centre_world, *frame_from_three(*(trial.parent_clean[:, i] for i in range(3))))
        assert np.ptp(truth, axis=0).max() < 1e-9  # the joint is fixed in the (noise-free) parent frame
        yield trial, parent, [to_local(trial.child[:, m], *parent) for m in range(5)], truth[0]


def test_functional_trial_20_degrees_2mm_noise():
    """The issue's case: a rigid 5-marker cluster ±20° in a moving parent, 2 mm noise. GDKE alone ≈ 8-10 mm."""
    refined, closed, score = [], [], []
    for trial, parent, local, truth in _functional_cases(20, 0.002, 5, seed=1):
        refined.append(np.linalg.norm(fit_joint(local).centre - truth))
        closed.append(np.linalg.norm(fit_joint(local, JointFitConfig(refine_iterations=0)).centre - truth))
        score.append(np.linalg.norm(score_centre(*parent, *cluster_poses(trial.child))[0] - truth))
    assert np.median(refined) < 0.0035 < np.median(closed)
    assert np.median(score) < 0.0035


def test_score_is_exact_without_noise():
    trial, parent, _, truth = next(_functional_cases(20, 0.0, 1, seed=2))
    centre_parent, centre_child = score_centre(*parent, *cluster_poses(trial.child))
    assert np.linalg.norm(centre_parent - truth) < 1e-9
    child = cluster_poses(trial.child)
    world = child[0] + np.einsum("fij,j->fi", child[1], centre_child)
    assert np.abs(world - trial.centre_world).max() < 1e-9


@pytest.mark.parametrize("dim", [2, 3])
def test_small_inverse_equals_numpy_and_refuses_a_singular_matrix(dim):
    rng = np.random.default_rng(dim)
    for _ in range(20):
        a = rng.normal(size=(dim, dim))
        m = a @ a.T + 0.1 * np.eye(dim)
        assert np.allclose(_inverse_small(m), np.linalg.inv(m), rtol=1e-10, atol=1e-12)
    with pytest.raises(np.linalg.LinAlgError):
        _inverse_small(np.zeros((dim, dim)))
