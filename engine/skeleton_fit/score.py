"""SCoRE, the symmetrical centre-of-rotation estimate (Ehrig et al., J. Biomech. 39 (2006) 2798-2809).

Why here: it is the standard two-segment peer of the single-segment sphere fit (paper 002), and the benchmark
compares both on the same functional trials. SCoRE uses both segments' poses: the joint centre is one point
fixed in the parent (c_p) and one fixed in the child (c_c) that coincide in the world at every frame,

    min over c_p, c_c of Σ_t |R_p(t) c_p + o_p(t) − R_c(t) c_c − o_c(t)|²,

a linear least-squares problem in 6 unknowns (one 6x6 normal system, accumulated in one vectorised pass).
It needs no sphere model and no choice of child marker, but each segment's pose comes from its own noisy
markers, so both segments' noise enters.
"""
from __future__ import annotations

import numpy as np

from .gdke import DegenerateFitError


def score_centre(parent_origin: np.ndarray, parent_rot: np.ndarray, child_origin: np.ndarray,
                 child_rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joint centre (c_p in the parent frame, c_c in the child frame) from per-frame poses.

    parent_origin/child_origin (F,3), parent_rot/child_rot (F,3,3) mapping local to world (columns = axes).
    Frames with any NaN are dropped. Raises DegenerateFitError when the relative rotation does not determine
    the centre (fewer than 2 distinct relative orientations)."""
    ok = ~(np.isnan(parent_origin).any(1) | np.isnan(child_origin).any(1)
           | np.isnan(parent_rot).any((1, 2)) | np.isnan(child_rot).any((1, 2)))
    if ok.sum() < 2:
        raise DegenerateFitError(f"SCoRE needs at least 2 frames with both segment poses, got {int(ok.sum())}")
    a = np.concatenate([parent_rot[ok], -child_rot[ok]], axis=2)  # (F, 3, 6)
    b = child_origin[ok] - parent_origin[ok]  # (F, 3)
    normal = np.einsum("fki,fkj->ij", a, a)
    rhs = np.einsum("fki,fk->i", a, b)
    evals = np.linalg.eigvalsh(normal)
    if evals[0] <= evals[-1] * 1e-12:
        raise DegenerateFitError(f"SCoRE: the segments do not rotate relative to each other (eigenvalues {evals})")
    solution = np.linalg.solve(normal, rhs)
    return solution[:3], solution[3:]


def cluster_poses(markers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pose (origin (F,3), rot (F,3,3)) of a marker cluster (F, M≥3, 3) relative to its first complete frame,
    by a least-squares rigid fit per frame (Kabsch, vectorised); NaN for frames with a missing marker."""
    complete = ~np.isnan(markers).any(axis=(1, 2))
    if not complete.any():
        raise DegenerateFitError("no frame has every marker of the cluster")
    template = markers[np.argmax(complete)]
    centred_t = template - template.mean(axis=0)
    origin = markers.mean(axis=1)
    cross = np.einsum("fmi,mj->fij", markers - origin[:, None], centred_t)  # Σ dst srcᵀ
    u, _, vt = np.linalg.svd(np.nan_to_num(cross))
    d = np.sign(np.linalg.det(u @ vt))
    rot = u @ (np.eye(3)[None] * np.stack([np.ones_like(d), np.ones_like(d), d], 1)[:, None, :]) @ vt
    rot[~complete] = np.nan
    origin[~complete] = np.nan
    return origin, rot
