"""GDKE sphere / circle / cylinder fits against exact synthetic answers (spec 002 §5)."""
from __future__ import annotations

import numpy as np
import pytest

from engine.skeleton_fit.gdke import (
    DegenerateFitError,
    JointFitConfig,
    JointType,
    circle_fit,
    cylinder_fit,
    fit_joint,
    kasa_lstsq_centre,
    plane_fit,
    sphere_fit,
)


def _sphere_points(rng, n, centre, radius):
    u = rng.normal(size=(n, 3))
    return centre + radius * u / np.linalg.norm(u, axis=1, keepdims=True)


def _rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _circle_points(rng, n, centre, radius, rot, arc_rad=2 * np.pi):
    t = rng.uniform(0, arc_rad, n)
    return centre + radius * np.stack([np.cos(t), np.sin(t), np.zeros(n)], 1) @ rot.T


def test_exact_sphere_and_circumsphere():
    rng = np.random.default_rng(1)
    for n in (4, 6, 50):
        centre, radius = rng.uniform(-1000, 1000, 3), rng.uniform(10, 500)
        fit = sphere_fit(_sphere_points(rng, n, centre, radius))
        assert np.allclose(fit.centre, centre, rtol=0, atol=1e-9 * radius)
        assert fit.radius == pytest.approx(radius, rel=1e-10)


def test_normalisation_regression_six_points():
    """S and C share one factor: 6 exact points of a radius-5 sphere at (10, 20, 30) give the centre exactly."""
    pts = np.array([10, 20, 30]) + 5 * np.vstack([np.eye(3), -np.eye(3)])
    assert np.allclose(sphere_fit(pts).centre, [10, 20, 30], atol=1e-12)


def test_equivalent_to_kasa_least_squares_and_equivariant():
    rng = np.random.default_rng(2)
    pts = _sphere_points(rng, 200, np.array([0.5, -0.2, 0.9]), 0.4) + rng.normal(0, 0.01, (200, 3))
    centre = sphere_fit(pts).centre
    assert np.allclose(centre, kasa_lstsq_centre(pts), atol=1e-12)
    rot, shift = _rotation(rng), rng.normal(size=3)
    moved = sphere_fit(pts @ rot.T + shift)
    assert np.allclose(moved.centre, rot @ centre + shift, atol=1e-12)
    assert moved.radius == pytest.approx(sphere_fit(pts).radius, rel=1e-12)


def test_monte_carlo_centre_error_follows_eq7():
    """|c − c0|·√N/σ over random N, σ/R ≤ 0.05: mean in [2.6, 3.1], std in [1.0, 1.45]; radius ≈ sqrt(R²+3σ²)."""
    rng = np.random.default_rng(7)
    errors, radius_ratio = [], []
    for _ in range(2000):
        n = int(rng.integers(4, 1001))
        radius = float(np.exp(rng.normal(0.18, 1.0)))
        sigma = radius * 10 ** rng.uniform(-4, np.log10(0.05))
        centre = np.array([0.6, -0.2, 0.9]) + rng.normal(0, 0.5, 3)
        fit = sphere_fit(_sphere_points(rng, n, centre, radius) + rng.normal(0, sigma, (n, 3)))
        errors.append(np.linalg.norm(fit.centre - centre) * np.sqrt(n) / sigma)
        if n >= 100:
            radius_ratio.append(fit.radius / np.sqrt(radius**2 + 3 * sigma**2))
    errors = np.array(errors)
    assert 2.6 <= errors.mean() <= 3.1, errors.mean()
    assert 1.0 <= errors.std() <= 1.45, errors.std()
    assert abs(np.mean(radius_ratio) - 1) < 2e-3


def test_missing_samples_are_ignored():
    rng = np.random.default_rng(3)
    pts = _sphere_points(rng, 100, np.array([0.5, 0.3, 0.9]), 0.3) + rng.normal(0, 1e-3, (100, 3))
    holed = pts.copy()
    holed[[5, 40, 77]] = np.nan
    assert np.allclose(sphere_fit(holed).centre, sphere_fit(np.delete(pts, [5, 40, 77], 0)).centre, atol=1e-14)


def test_circle_hinge_classification_and_axis():
    rng = np.random.default_rng(4)
    rot, centre = _rotation(rng), np.array([0.1, 0.9, -0.4])
    pts = _circle_points(rng, 100, centre, 1.0, rot) + rng.normal(0, 0.01, (100, 3))
    fit = fit_joint(pts, JointFitConfig(static_std=0.03))
    assert fit.kind is JointType.HINGE and fit.kappa > 1e3
    assert abs(fit.axis @ rot[:, 2]) > 0.999
    assert np.linalg.norm(fit.centre - centre) < 6e-3
    assert fit.radius == pytest.approx(1.0, abs=0.01)


def test_exactly_planar_and_three_point_circumcircle():
    rng = np.random.default_rng(5)
    rot, centre = _rotation(rng), rng.normal(size=3)
    exact = _circle_points(rng, 30, centre, 2.0, rot)
    assert np.allclose(circle_fit(exact).centre, centre, atol=1e-9)
    assert fit_joint(exact, JointFitConfig(static_std=0.0)).kind is JointType.HINGE
    three = _circle_points(rng, 3, centre, 2.0, rot)
    assert np.allclose(circle_fit(three).centre, centre, atol=1e-9)
    assert abs(plane_fit(exact).normal @ rot[:, 2]) == pytest.approx(1.0, abs=1e-12)


def test_cylinder_pools_markers_at_different_heights():
    """Two markers circling one axis at different heights and radii share the axis point and direction."""
    rng = np.random.default_rng(6)
    rot, centre = _rotation(rng), np.array([0.2, 0.5, 0.1])
    a = _circle_points(rng, 80, centre, 0.30, rot, arc_rad=2.0)
    b = _circle_points(rng, 80, centre + 0.1 * rot[:, 2], 0.45, rot, arc_rad=2.0)
    fit = cylinder_fit([a, b])
    assert abs(fit.axis @ rot[:, 2]) == pytest.approx(1.0, abs=1e-10)
    off_axis = (fit.point - centre) - ((fit.point - centre) @ rot[:, 2]) * rot[:, 2]
    assert np.linalg.norm(off_axis) < 1e-9
    assert np.allclose(sorted(fit.radii), [0.30, 0.45], atol=1e-9)


def test_ball_joint_pools_markers_with_different_radii():
    rng = np.random.default_rng(8)
    centre = np.array([0.1, -0.3, 0.2])
    trajs = [_sphere_points(rng, 100, centre, r) + rng.normal(0, 1e-3, (100, 3)) for r in (0.2, 0.35)]
    fit = fit_joint(trajs)
    assert fit.kind is JointType.BALL
    assert np.linalg.norm(fit.centre - centre) < 3 * 2.9 * 1e-3 / np.sqrt(200)  # 3x the Eq. 7 expectation


def test_stationary_marker_is_static():
    rng = np.random.default_rng(9)
    pts = np.array([0.4, 1.0, 0.2]) + rng.normal(0, 1e-6, (60, 3))
    assert fit_joint(pts).kind is JointType.STATIC


@pytest.mark.parametrize(
    "points, message",
    [
        (np.ones((3, 3)), "at least 4"),
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 3, 0.0]]), "coplanar"),
        (np.full((10, 3), np.nan), "at least 4"),
    ],
)
def test_degenerate_sphere_inputs_raise_clear_errors(points, message):
    with pytest.raises(DegenerateFitError, match=message):
        sphere_fit(points)


def test_collinear_points_have_no_circle_and_bad_shape_is_rejected():
    line = np.outer(np.linspace(0, 1, 10), [1.0, 2.0, 3.0])
    with pytest.raises(DegenerateFitError, match="collinear"):
        circle_fit(line)
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        sphere_fit(np.zeros((10, 2)))
