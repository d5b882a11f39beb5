"""Segment coordinate frames from markers (paper 002 §2.4, cases 1-3), vectorised over frames.

Why relative vectors: the paper's cross products, read literally on absolute positions, depend on the world
origin. Applying them to the defining points minus their centroid ``g`` gives the same construction but rigidly
attached to the segment (spec §2.8). The same functions are used for analysis (fitting) and playback, so a joint
centre stored in a segment frame is reproduced exactly.

Every function returns ``(origin (F,3), rot (F,3,3))`` where ``rot[f]`` has the segment axes x̂, ŷ, ẑ as columns
(right-handed, orthonormal) and ``origin`` is the centroid of the defining points. Frames with a missing (NaN)
defining point, or with collinear points, come out NaN.
"""
from __future__ import annotations

import numpy as np


def _unit(v: np.ndarray, eps: float = 1e-12) -> np.ndarray:
    """Normalise the last axis; near-zero vectors become NaN (collinear points define no frame)."""
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(norm > eps, v / np.where(norm > eps, norm, 1.0), np.nan)


def _assemble(q0: np.ndarray, x_axis: np.ndarray) -> np.ndarray:
    """ẑ ∝ q0 × x̂, ŷ = ẑ × x̂, stacked as columns [x̂ ŷ ẑ]."""
    x_hat = _unit(x_axis)
    z_hat = _unit(np.cross(q0, x_hat))
    y_hat = np.cross(z_hat, x_hat)
    return np.stack([x_hat, y_hat, z_hat], axis=-1)


def frame_from_three(p0: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Case 3 (three non-collinear markers) and case 2 (pass the rotation centre as ``p2``): x̂ ∝ q2 × q1."""
    p0, p1, p2 = (np.asarray(p, dtype=float) for p in (p0, p1, p2))
    g = (p0 + p1 + p2) / 3.0
    q0, q1, q2 = p0 - g, p1 - g, p2 - g
    return g, _assemble(q0, np.cross(q2, q1))


def frame_from_axis(p0: np.ndarray, centre: np.ndarray, axis_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Case 1 (one marker, the rotation centre and the hinge axis in world coordinates): x̂ = axis."""
    p0, centre = np.asarray(p0, dtype=float), np.asarray(centre, dtype=float)
    g = (p0 + centre) / 2.0
    return g, _assemble(p0 - g, np.asarray(axis_world, dtype=float))


def to_local(points: np.ndarray, origin: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """World points (F,3) into the frame (origin (F,3), rot (F,3,3)): Rᵀ (x − o)."""
    return np.einsum("fji,fj->fi", rot, points - origin)


def to_world(local: np.ndarray, origin: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """A constant local point (3,) or per-frame local points (F,3) into world coordinates: o + R v."""
    local = np.broadcast_to(np.asarray(local, dtype=float), origin.shape)
    return origin + np.einsum("fij,fj->fi", rot, local)
