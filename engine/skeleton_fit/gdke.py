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
    min_points: fewer valid points than this is an error (4 determine a sphere).
    refine_iterations: Levenberg-Marquardt steps on the geometric residual |x − c| − R_m started from the closed
        form (0 = GDKE only). Why: GDKE minimises the *algebraic* residual |x − c|² − R², which weights points by
        their distance and carries a bias on partial arcs that more data does not remove (60° cap, N = 10⁴:
        24·σ/√N; 30° cap: 402·σ/√N); the geometric optimum has no such bias, and from the GDKE start a few
        steps reach it.
    refine_tol: stop when a step moves the centre by less than this (input unit; 1 µm in metres).
    outlier_k: after the refinement, points whose geometric residual exceeds this many robust sigmas are dropped
        and the fit refined again (0 = keep every point; see refine_centre)."""

    kappa_max: float = 300.0
    static_std: float = 3e-3
    min_points: int = 4
    refine_iterations: int = 8
    refine_tol: float = 1e-6
    outlier_k: float = 5.0


@dataclass(frozen=True)
class JointFit:
    """Result of the ball-vs-hinge decision for one marker trajectory in its parent frame.

    arc_deg: half-angle of the cone the marker directions sweep about the centre (90 = a hemisphere or more;
        a partial arc is where the closed form is biased and the expected error grows).
    expected_error: predicted RMS centre error, sqrt(trace(σ̂² (JᵀJ)⁻¹)) of the geometric fit (input unit);
        on a full sphere it is ≈ 3σ/√N, the paper's Eq. 7."""

    kind: JointType
    centre: np.ndarray  # (3,) rotation centre (ball) or the circle centre on the hinge axis; NaN when static
    axis: np.ndarray | None  # (3,) unit hinge axis (hinge only)
    radius: float  # distance marker→centre (NaN when static)
    kappa: float  # condition number of C
    n_points: int
    arc_deg: float = float("nan")
    expected_error: float = float("nan")
    iterations: int = 0  # geometric refinement steps taken (0: closed form only)


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
    valid = [valid_points(t) for t in trajs]
    stats = [_moments_of_valid(t, config.min_points) for t in valid]
    moving = [i for i, m in enumerate(stats) if _moves(m.cov, config.static_std**2)]  # sqrt(λ_max) ≥ static_std
    n_points = sum(m.n for m in stats)
    if not moving:
        return JointFit(JointType.STATIC, np.full(3, np.nan), None, float("nan"), float("inf"), n_points)
    cov_sum, rhs = pooled_normal_equations([stats[i] for i in moving])
    evals, evecs = np.linalg.eigh(cov_sum)
    kappa = float(evals[-1] / evals[0]) if evals[0] > 0 else float("inf")
    used = [valid[i] for i in moving]
    if kappa <= config.kappa_max:
        start = evecs @ ((evecs.T @ rhs) / evals)  # the closed form, solved with the eigen-decomposition in hand
        geo = refine_centre(used, start, config.refine_iterations, config.refine_tol, outlier_k=config.outlier_k)
        return JointFit(JointType.BALL, geo.centre, None, geo.radius, kappa, n_points, geo.arc_deg,
                        geo.expected_error, geo.iterations)
    cylinder = cylinder_fit(used)
    basis = np.linalg.svd(np.eye(3) - np.outer(cylinder.axis, cylinder.axis))[0][:, :2]  # in-plane axes
    heights = [float(np.mean(t @ cylinder.axis)) for t in used]
    flat = [(t - cylinder.point) @ basis for t in used]  # project on the plane ⊥ axis, origin on the axis
    geo = refine_centre(flat, np.zeros(2), config.refine_iterations, config.refine_tol, outlier_k=config.outlier_k)
    point = cylinder.point + basis @ geo.centre
    point = point + (np.mean(heights) - point @ cylinder.axis) * cylinder.axis
    return JointFit(JointType.HINGE, point, cylinder.axis, geo.radius, kappa, n_points, geo.arc_deg,
                    geo.expected_error, geo.iterations)


@dataclass(frozen=True)
class GeometricFit:
    """Result of refine_centre: centre (D,), mean radius, expected RMS centre error, arc half-angle, steps."""

    centre: np.ndarray
    radius: float
    expected_error: float
    arc_deg: float
    iterations: int


def refine_centre(trajectories: list[np.ndarray], start: np.ndarray, iterations: int = 8,
                  tol: float = 1e-6, rel_tol: float = 0.01, outlier_k: float = 0.0) -> GeometricFit:
    """Levenberg-Marquardt on the geometric residual r_i = |x_i − c| − R_m, one free radius R_m per marker.

    Works in 3-D (sphere) or 2-D (circle, points projected on the hinge plane). The radii are eliminated
    (variable projection: for a given c the best R_m is the mean distance of marker m), so the Jacobian is
    J_i = ū_m − u_i with u_i the unit vector from c to x_i, and each step needs only JᵀJ = Σ u uᵀ − Σ_m N_m ū_m ū_mᵀ
    and Jᵀr = −Σ u_i r_i (Σ r_i = 0 per marker): one O(N) pass and a D×D solve. Started from the closed form,
    which is close to the optimum, it converges in 2-4 steps; the damping only matters on nearly degenerate arcs.
    Expected error: sqrt(trace(σ̂² (JᵀJ)⁻¹)) with σ̂² = Σr²/(N − D − M). Stops when a step is below ``tol`` or
    below ``rel_tol`` x the expected error (statistically nothing left to gain; 0 = iterate to ``tol``).
    outlier_k > 0: if some residuals exceed outlier_k robust sigmas (1.4826 x median |r|), those points are
    dropped (each marker keeps at least 4) and the fit is refined again from the current centre. Why: a least-
    squares sphere is not robust, and labelled capture has a few frames where a marker was mislabelled or the
    parent frame was built from a wrong marker; on the two-player tennis serve 1-3 % such frames moved a hip
    centre by 10 cm. Checking after the fit costs one partition; the refit happens only when needed."""
    pts = [np.asarray(t, float) for t in trajectories]
    sizes = np.array([len(t) for t in pts])
    bounds = np.concatenate([[0], np.cumsum(sizes)])
    x = np.concatenate(pts).T.copy()  # (D, N): per-coordinate rows keep the reductions contiguous
    dim, n = x.shape
    n_markers = len(pts)

    def evaluate(c: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        rel = x - c[:, None]
        dist = np.sqrt(np.einsum("in,in->n", rel, rel))
        unit = rel / dist
        if n_markers == 1:  # the common case, without the per-marker loop (sums: cheaper than mean here)
            mean_d = np.array([dist.sum() / n])
            res = dist - mean_d[0]
            u_sum = unit.sum(axis=1)
            jtj = unit @ unit.T - np.outer(u_sum, u_sum) / n
        else:
            res = np.empty(n)
            jtj = unit @ unit.T
            mean_d = np.empty(n_markers)
            for m in range(n_markers):
                sl = slice(bounds[m], bounds[m + 1])
                mean_d[m] = dist[sl].mean()
                res[sl] = dist[sl] - mean_d[m]
                u_mean = unit[:, sl].mean(axis=1)
                jtj -= sizes[m] * np.outer(u_mean, u_mean)
        return float(res @ res), jtj, -(unit @ res), mean_d, unit, res

    centre = np.asarray(start, float).copy()
    cost, jtj, jtr, mean_d, unit, res = evaluate(centre)
    dof = max(n - dim - n_markers, 1)
    lam, steps, eye, covariance = 0.0, 0, np.eye(dim), None
    for _ in range(iterations):  # Gauss-Newton; Levenberg-Marquardt damping only after a step that failed
        inverse = _inverse_small(jtj + lam * np.trace(jtj) / dim * eye)
        step = -(inverse @ jtr)
        if lam == 0.0 and step @ step < rel_tol**2 * cost / dof * np.trace(inverse):
            covariance = inverse  # (JᵀJ)⁻¹ at the final centre: reused for the expected error
            break  # the step is far below the expected error: statistically nothing left to gain
        trial = centre + step
        steps += 1
        evaluated = evaluate(trial)
        if evaluated[0] <= cost:
            centre, (cost, jtj, jtr, mean_d, unit, res) = trial, evaluated
            lam *= 0.1
            if step @ step < tol * tol:
                break
        else:
            lam = max(lam * 10.0, 1e-4)
    try:
        covariance = _inverse_small(jtj) if covariance is None else covariance
        expected = float(np.sqrt(cost / dof * np.trace(covariance)))
    except np.linalg.LinAlgError:  # a direction the data do not constrain at all
        expected = float("inf")
    if outlier_k > 0:
        magnitude = np.abs(res)
        limit = outlier_k * 1.4826 * float(np.partition(magnitude, n // 2)[n // 2])  # ≈ median, one O(N) pass
        outlier = magnitude > limit
        if limit > 0 and outlier.any():
            kept = [t[~outlier[bounds[m] : bounds[m + 1]]] for m, t in enumerate(pts)]
            kept = [k if len(k) >= 4 else t for k, t in zip(kept, pts)]
            if sum(len(k) for k in kept) < n:
                return refine_centre(kept, centre, iterations, tol, rel_tol)
    arcs = [_arc_deg(unit[:, bounds[m] : bounds[m + 1]]) for m in range(n_markers)]
    arc = arcs[0] if n_markers == 1 else float(np.median(arcs))  # np.median's set-up costs more than a small fit
    return GeometricFit(centre, float(mean_d.sum() / n_markers), expected, arc, steps)


def _inverse_small(m: np.ndarray) -> np.ndarray:
    """Inverse of a 2x2 or 3x3 matrix by cofactors. Why: np.linalg.inv costs ~50 µs per call on a 3x3 (its
    generic set-up, not the arithmetic); two calls were half of fit_joint's time at N = 10, which decides whether
    the refined fit is 5x faster than iterative least squares on small caps. Raises LinAlgError when singular."""
    if m.shape == (2, 2):
        a, b, c, d = m.ravel().tolist()
        det = a * d - b * c
        if det == 0.0:
            raise np.linalg.LinAlgError("singular matrix")
        return np.array([[d, -b], [-c, a]]) / det
    a, b, c, d, e, f, g, h, i = m.ravel().tolist()
    co = [e * i - f * h, c * h - b * i, b * f - c * e,
          f * g - d * i, a * i - c * g, c * d - a * f,
          d * h - e * g, b * g - a * h, a * e - b * d]
    det = a * co[0] + b * co[3] + c * co[6]
    if det == 0.0:
        raise np.linalg.LinAlgError("singular matrix")
    return np.array(co).reshape(3, 3) / det


def _arc_deg(unit: np.ndarray) -> float:
    """Half-angle of the cap or arc one marker swept: the largest angle between its directions from the centre
    (unit vectors, (D, N)) and their mean direction (90° = a hemisphere, small = a short arc)."""
    axis = unit.sum(axis=1)
    cos_min = float((axis @ unit).min() / max(float(np.sqrt(axis @ axis)), 1e-300))
    return float(np.degrees(np.arccos(min(max(cos_min, -1.0), 1.0))))


def _moves(cov: np.ndarray, threshold: float) -> bool:
    """λ_max(cov) ≥ threshold, for a 3x3 covariance. trace/3 ≤ λ_max ≤ trace decides most cases without the
    eigen-solve (which costs as much as the closed-form fit itself)."""
    trace = float(np.trace(cov))
    if trace < threshold or trace / 3.0 >= threshold:
        return trace >= threshold
    return float(np.linalg.eigvalsh(cov)[-1]) >= threshold


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
