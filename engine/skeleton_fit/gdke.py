"""Closed-form rotation-centre fits: GDKE sphere, plane, circle (paper 002 Eq. 6) and hinge axis.

Why closed form: the Generalized Delogne-Kåsa Estimator (Knight & Semwal) minimises the variance of the squared
radii, which reduces to one pass of moments (mean, 3x3 covariance ``C``, third-moment vector ``S``) and one 3x3
solve ``c = x̄ + ½ C⁻¹ S``. No initial guess, no iterations, nothing to diverge, O(N).

All fits work in coordinates centred on the data (``y = x − x̄``) because raw moments of world-frame millimetre
values lose precision. ``C`` and ``S`` share the same 1/(N−1) factor: only their ratio matters, and mixing
normalisations silently moves the centre (spec §2.1).

Missing samples (any NaN coordinate) are dropped before anything else, because zeroed or NaN frames are
disastrous for a moment-based estimator. Callers holding C3D "zero = missing" data convert zeros to NaN first.
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from engine.errors import CourtsideError


class DegenerateFitError(CourtsideError, ValueError):
    """The points cannot define the requested shape (too few, collinear, coplanar, or not moving)."""


class JointType(str, Enum):
    """What the condition-number test decided about a joint's motion."""

    BALL = "ball"  # spherical: 2-3 rotational DOF, centre from Eq. 5
    HINGE = "hinge"  # planar marker path: 1 DOF, centre from Eq. 6, axis = plane normal
    STATIC = "static"  # the marker does not move relative to the parent: no centre exists


@dataclass(frozen=True)
class Moments:
    """Centred moments of a point set (paper Eqs. 2-4).

    mean: (3,) x̄; cov: (3,3) C = Σ y yᵀ/(N−1); third: (3,) S = Σ y |y|²/(N−1); n: number of valid points."""

    mean: np.ndarray
    cov: np.ndarray
    third: np.ndarray
    n: int


@dataclass(frozen=True)
class SphereFit:
    centre: np.ndarray  # (3,) same unit as the input
    radius: float  # root-mean-square distance of the points from the centre


@dataclass(frozen=True)
class PlaneFit:
    point: np.ndarray  # (3,) the data mean, a point on the plane
    normal: np.ndarray  # (3,) unit normal (eigenvector of C with the smallest eigenvalue)
    residual_var: float  # variance of the signed distances to the plane = λ_min(C)


@dataclass(frozen=True)
class CircleFit:
    centre: np.ndarray  # (3,) circle centre c' in the plane through the data mean (Eq. 6)
    normal: np.ndarray  # (3,) unit plane normal = hinge axis direction
    radius: float  # RMS in-plane distance of the points from the centre


@dataclass(frozen=True)
class JointFitConfig:
    """Thresholds of the joint-type decision (spec §2.6, all configurable).

    kappa_max: condition number λ_max/λ_min of C above which the motion counts as planar (hinge). The spec
        suggests 1e3; 300 is used because real skin markers blur the hinge plane: the biobuddy knee trial gives
        κ = 420-1160 per shank marker (643 pooled) while its hip trial gives 27-78 per thigh marker. Synthetic
        spherical caps down to 20° half-angle stay below ~83 and noisy arcs ≥45° above ~2e3 (spec §2.6).
    static_std: a marker whose largest principal standard deviation sqrt(λ_max(C)) is below this (input unit)
        is "not moving"; set it to about 3× the measurement noise.
    min_points: fewer valid points than this is an error (4 determine a sphere)."""

    kappa_max: float = 300.0
    static_std: float = 3e-3
    min_points: int = 4


@dataclass(frozen=True)
class JointFit:
    """Result of the ball-vs-hinge decision for one marker trajectory in its parent frame."""

    kind: JointType
    centre: np.ndarray  # (3,) rotation centre (ball) or the circle centre on the hinge axis; NaN when static
    axis: np.ndarray | None  # (3,) unit hinge axis (hinge only)
    radius: float  # distance marker→centre (NaN when static)
    kappa: float  # condition number of C
    n_points: int


def valid_points(points: np.ndarray) -> np.ndarray:
    """(N,3) float array with rows containing any NaN removed. Raises on a wrong shape."""
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {pts.shape}")
    return pts[~np.isnan(pts).any(axis=1)]


def moments(points: np.ndarray, min_points: int = 4) -> Moments:
    """Centred moments of the valid points. O(N), vectorised."""
    return _moments_of_valid(valid_points(points), min_points)


def _moments_of_valid(pts: np.ndarray, min_points: int) -> Moments:
    n = len(pts)
    if n < min_points:
        raise DegenerateFitError(f"need at least {min_points} valid points, got {n}")
    mean = pts.mean(axis=0)
    y = pts - mean
    cov = y.T @ y / (n - 1)
    third = y.T @ np.einsum("ij,ij->i", y, y) / (n - 1)
    return Moments(mean, cov, third, n)


def sphere_fit(points: np.ndarray) -> SphereFit:
    """GDKE sphere centre c = x̄ + ½ C⁻¹ S (Eq. 5) and RMS radius.

    Raises DegenerateFitError when fewer than 4 points or the points are coplanar (C singular)."""
    pts = valid_points(points)
    m = _moments_of_valid(pts, 4)
    # Coplanar data make C singular; the determinant test relative to the scale of C is a cheap 3x3 check.
    scale = np.trace(m.cov) / 3.0
    if scale <= 0 or np.linalg.det(m.cov) <= (scale**3) * 1e-12:
        raise DegenerateFitError(
            f"points are coplanar or collinear (eigenvalues of C {np.linalg.eigvalsh(m.cov)}); "
            "a sphere is undetermined — use circle_fit"
        )
    centre = m.mean + 0.5 * np.linalg.solve(m.cov, m.third)
    return SphereFit(centre, _rms_radius(pts, centre))


def plane_fit(points: np.ndarray) -> PlaneFit:
    """Best-fit plane: normal = eigenvector of C with the smallest eigenvalue (spec §2.2). Needs 3 points."""
    m = moments(points, 3)
    evals, evecs = np.linalg.eigh(m.cov)
    if evals[1] <= max(evals[2], 0.0) * 1e-12:
        raise DegenerateFitError(f"points are collinear or coincident (eigenvalues of C {evals}); no plane")
    return PlaneFit(m.mean, evecs[:, 0], float(max(evals[0], 0.0)))


def circle_fit(points: np.ndarray) -> CircleFit:
    """Circle centre c' = x̄ + ½ C⁺ S with the plane-normal direction dropped (Eq. 6, pseudo-inverse form).

    Works for exactly planar data, where Eq. 5 would divide by zero. Three non-collinear points give their
    circumcircle."""
    cylinder = cylinder_fit([points])
    return CircleFit(cylinder.point, cylinder.axis, float(cylinder.radii[0]))


def kasa_lstsq_centre(points: np.ndarray) -> np.ndarray:
    """Classic linear (Kåsa) sphere fit |x|² = 2x·c + k by least squares on the centred data.

    Algebraically identical to GDKE; kept as the reference the tests and the benchmark compare against."""
    pts = valid_points(points)
    mean = pts.mean(axis=0)
    y = pts - mean
    a = np.hstack([2.0 * y, np.ones((len(y), 1))])
    sol, *_ = np.linalg.lstsq(a, np.einsum("ij,ij->i", y, y), rcond=None)
    return mean + sol[:3]


def fit_joint(trajectories: np.ndarray | list[np.ndarray], config: JointFitConfig = JointFitConfig()) -> JointFit:
    """Decide ball / hinge / static from the eigenvalues of C and return the matching centre (spec §2.6).

    trajectories: one (N,3) trajectory, or a list of them, of child markers expressed in the parent segment frame
    (NaN rows = missing). Several markers are pooled with one free radius each (see pooled_normal_equations);
    markers that do not move (sqrt λ_max(C) < static_std) are left out, and if none moves the joint is STATIC."""
    trajs = [trajectories] if isinstance(trajectories, np.ndarray) and trajectories.ndim == 2 else list(trajectories)
    stats = [moments(t, config.min_points) for t in trajs]
    moving = [i for i, m in enumerate(stats) if np.sqrt(max(np.linalg.eigvalsh(m.cov)[-1], 0.0)) >= config.static_std]
    n_points = sum(m.n for m in stats)
    if not moving:
        return JointFit(JointType.STATIC, np.full(3, np.nan), None, float("nan"), float("inf"), n_points)
    cov_sum, rhs = pooled_normal_equations([stats[i] for i in moving])
    evals, evecs = np.linalg.eigh(cov_sum)
    kappa = float(evals[-1] / evals[0]) if evals[0] > 0 else float("inf")
    used = [valid_points(trajs[i]) for i in moving]
    if kappa <= config.kappa_max:
        centre = np.linalg.solve(cov_sum, rhs)
        radius = float(np.mean([_rms_radius(t, centre) for t in used]))
        return JointFit(JointType.BALL, centre, None, radius, kappa, n_points)
    cylinder = cylinder_fit(used)
    return JointFit(JointType.HINGE, cylinder.point, cylinder.axis, float(np.mean(cylinder.radii)), kappa, n_points)


def pooled_normal_equations(stats: list[Moments]) -> tuple[np.ndarray, np.ndarray]:
    """(Σ C_m, Σ (C_m μ_m + ½ S_m)) for markers sharing one centre but each with its own radius.

    Minimising Σ_m Σ_i (|x_i|² − 2 x_i·c − k_m)² over c and one k_m per marker eliminates k_m by centring each
    marker on its own mean, leaving (Σ C_m) c = Σ (C_m μ_m + ½ S_m). One marker gives exactly Eq. 5. Each marker
    is weighted by its N−1 (the moments carry 1/(N−1))."""
    if not stats:
        raise DegenerateFitError("no marker trajectories to fit")
    cov_sum = sum((m.n - 1) * m.cov for m in stats)
    rhs = sum((m.n - 1) * (m.cov @ m.mean + 0.5 * m.third) for m in stats)
    return cov_sum, rhs


def _rms_radius(points: np.ndarray, centre: np.ndarray) -> float:
    rel = points - centre
    return float(np.sqrt(np.mean(np.einsum("ij,ij->i", rel, rel))))


@dataclass(frozen=True)
class CylinderFit:
    point: np.ndarray  # (3,) a point on the axis (at the mean height of the markers along the axis)
    axis: np.ndarray  # (3,) unit axis direction
    radii: np.ndarray  # (M,) RMS distance of each marker from the axis


def cylinder_fit(trajectories: list[np.ndarray]) -> CylinderFit:
    """Hinge axis from one or more markers circling it at different heights (extension of spec §2.4).

    Each marker m gets its own free constant in |x|² = 2x·c + k_m, which eliminates by centring every marker on
    its own mean (pooled_normal_equations), solved in the plane perpendicular to the axis. The axis is the
    smallest-eigenvalue direction of Σ C_m, i.e. the normal every marker's plane of motion shares. One marker reduces exactly to circle_fit."""
    cov_sum, rhs = pooled_normal_equations([moments(t, 3) for t in trajectories])
    stats_means = [valid_points(t).mean(axis=0) for t in trajectories]
    evals, evecs = np.linalg.eigh(cov_sum)
    if evals[1] <= max(evals[2], 0.0) * 1e-12:
        raise DegenerateFitError(f"marker paths are collinear (eigenvalues {evals}); no rotation axis")
    axis, in_plane = evecs[:, 0], evecs[:, 1:]
    centre_2d = (in_plane.T @ rhs) / evals[1:]
    height = float(np.mean([mean @ axis for mean in stats_means]))
    point = in_plane @ centre_2d + height * axis
    radii = []
    for t in trajectories:
        rel = valid_points(t) - point
        perp = rel - np.outer(rel @ axis, axis)
        radii.append(np.sqrt(np.mean(np.einsum("ij,ij->i", perp, perp))))
    return CylinderFit(point, axis, np.asarray(radii))
