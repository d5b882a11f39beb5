"""Kovar point-cloud pose distance, vectorised as matrix products.

The distance between frame a of one clip and frame b of another is the weighted squared distance between the
joint-position point clouds of a short window of frames around each, minimised over a 2-D rigid transform of
the ground plane (rotation about Y + translation in X-Z). Kovar et al. give the optimum in closed form; here
the same optimum is written so that all pairs are computed by GEMMs:

    D(a, b) = c_a + c_b - 2 Y_a.Y_b - 2 sqrt((U_a.U_b)^2 + (U_a.V_b)^2)

with, per window and with weights w summing to 1, centred ground coordinates (x~, z~) and heights y,
c = sum w (x~^2 + z~^2 + y^2), U = sqrt(w) (x~, z~), V = sqrt(w) (z~, -x~), Y = sqrt(w) y.
The optimal rotation is atan2(U_a.V_b, U_a.U_b). We report sqrt(D): an RMS point distance in metres, so
thresholds read as "poses differ by about this many metres per point".
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class WindowFeatures:
    """Per-window features of the closed-form distance; row i describes the window centred on `centres[i]`."""

    centres: np.ndarray  # (K,) int, frame index of each window centre
    c: np.ndarray  # (K,) weighted second moment, m^2
    u: np.ndarray  # (K, 2kJ) sqrt(w) * (x~, z~)
    v: np.ndarray  # (K, 2kJ) sqrt(w) * (z~, -x~)
    y: np.ndarray  # (K, kJ) sqrt(w) * y


def window_weights(window_frames: int, joint_weights: np.ndarray) -> np.ndarray:
    """(k, J) weights summing to one: a uniform window times the per-joint weights."""
    jw = np.asarray(joint_weights, dtype=float)
    if jw.ndim != 1 or np.any(jw < 0) or jw.sum() <= 0:
        raise ValueError("joint weights must be a non-negative 1-D vector with a positive sum")
    w = np.repeat(jw[None, :], window_frames, axis=0)
    return w / w.sum()


def window_features(positions_m: np.ndarray, centres: np.ndarray, window_frames: int,
                    joint_weights: np.ndarray) -> WindowFeatures:
    """Features of the windows centred on `centres` (frames whose window would leave the clip are clamped
    to the clip, i.e. the end frames repeat -- callers normally pass only centres whose window fits)."""
    positions_m = np.asarray(positions_m, dtype=float)
    n_frames = positions_m.shape[0]
    half = window_frames // 2
    centres = np.asarray(centres, dtype=np.int64)
    idx = np.clip(centres[:, None] + np.arange(-half, window_frames - half)[None, :], 0, n_frames - 1)
    win = positions_m[idx]  # (K, k, J, 3)
    w = window_weights(window_frames, joint_weights)  # (k, J)
    cx = np.einsum("kfj,fj->k", win[..., 0], w)
    cz = np.einsum("kfj,fj->k", win[..., 2], w)
    xt = win[..., 0] - cx[:, None, None]
    zt = win[..., 2] - cz[:, None, None]
    yy = win[..., 1]
    c = np.einsum("kfj,fj->k", xt * xt + zt * zt + yy * yy, w)
    sw = np.sqrt(w)[None]
    k = len(centres)
    u = np.concatenate([(sw * xt).reshape(k, -1), (sw * zt).reshape(k, -1)], axis=1)
    v = np.concatenate([(sw * zt).reshape(k, -1), (-sw * xt).reshape(k, -1)], axis=1)
    return WindowFeatures(centres=centres, c=c, u=u, v=v, y=(sw * yy).reshape(k, -1))


def distance_matrix(a: WindowFeatures, b: WindowFeatures, chunk_rows: int = 2048) -> np.ndarray:
    """RMS point-cloud distance (m) between every window of `a` (rows) and every window of `b` (columns)."""
    out = np.empty((len(a.c), len(b.c)))
    for start in range(0, len(a.c), chunk_rows):
        sl = slice(start, start + chunk_rows)
        dot_u = a.u[sl] @ b.u.T
        dot_v = a.u[sl] @ b.v.T
        d2 = a.c[sl, None] + b.c[None, :] - 2.0 * (a.y[sl] @ b.y.T) - 2.0 * np.hypot(dot_u, dot_v)
        out[sl] = np.sqrt(np.maximum(d2, 0.0))
    return out


def optimal_alignment(a: WindowFeatures, ia: int, b: WindowFeatures, ib: int) -> float:
    """Rotation (rad, about +Y) that best maps window `ib` of `b` onto window `ia` of `a`."""
    return float(np.arctan2(a.u[ia] @ b.v[ib], a.u[ia] @ b.u[ib]))
