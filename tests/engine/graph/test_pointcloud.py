"""Closed-form point-cloud distance against a brute-force minimisation over the ground-plane rigid transform."""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from engine.graph.geometry import rotate_points_y
from engine.graph.pointcloud import distance_matrix, optimal_alignment, window_features, window_weights


def brute_force_rms(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> float:
    """min over (theta, tx, tz) of sqrt(sum w |a - T b|^2), by numerical optimisation from several starts."""
    def f(x):
        tb = rotate_points_y(b, x[0])
        tb[..., 0] += x[1]
        tb[..., 2] += x[2]
        return float(np.sum(w[..., None] * (a - tb) ** 2))
    best = min((minimize(f, [th, 0, 0], method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-14,
                                                                            "maxiter": 20000})
                for th in np.linspace(-np.pi, np.pi, 8, endpoint=False)), key=lambda r: r.fun)
    return float(np.sqrt(best.fun))


def test_distance_matches_brute_force_on_random_clouds():
    rng = np.random.default_rng(1)
    k, j = 5, 4
    a = rng.normal(size=(k, j, 3))
    b = rng.normal(size=(k, j, 3))
    jw = rng.uniform(0.5, 2.0, j)
    fa = window_features(a, np.array([2]), k, jw)
    fb = window_features(b, np.array([2]), k, jw)
    d = distance_matrix(fa, fb)[0, 0]
    assert abs(d - brute_force_rms(a, b, window_weights(k, jw))) < 1e-5


def test_rigidly_moved_copy_has_zero_distance_and_known_rotation():
    rng = np.random.default_rng(2)
    clip = rng.normal(size=(20, 6, 3))
    angle = 0.8
    moved = rotate_points_y(clip, -angle)
    moved[..., 0] += 3.0
    moved[..., 2] -= 1.5
    centres = np.arange(3, 17)
    fa = window_features(clip, centres, 7, np.ones(6))
    fb = window_features(moved, centres, 7, np.ones(6))
    d = distance_matrix(fa, fb, chunk_rows=4)  # chunking must not change the answer
    assert np.allclose(np.diag(d), 0.0, atol=1e-6)
    off = d[~np.eye(len(centres), dtype=bool)]
    assert off.min() > 0.1  # different frames of random data are far apart
    assert abs(optimal_alignment(fa, 5, fb, 5) - angle) < 1e-9
