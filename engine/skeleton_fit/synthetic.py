"""Synthetic joint-centre data with exact answers: spherical caps and rigid-cluster functional trials.

Why in the package: the tests (known centres on partial arcs) and bench/bench_sphere_fit.py must draw the same
kind of data, and a real joint sweeps a partial arc, not the full sphere of the paper's Monte Carlo (issue 14).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def spherical_cap(rng: np.random.Generator, n: int, half_angle_deg: float, radius: float, sigma: float,
                  centre: np.ndarray | None = None) -> np.ndarray:
    """n points uniform on the cap of half-angle ``half_angle_deg`` (180 = full sphere) about a random axis,
    plus isotropic Gaussian noise σ per coordinate. Centre at ``centre`` (default: the origin)."""
    z = rng.uniform(np.cos(np.radians(half_angle_deg)), 1.0, n)
    phi = rng.uniform(0.0, 2 * np.pi, n)
    ring = np.sqrt(1.0 - z * z)
    local = np.stack([ring * np.cos(phi), ring * np.sin(phi), z], axis=1)
    rot = random_rotation(rng)
    origin = np.zeros(3) if centre is None else np.asarray(centre, float)
    return origin + radius * local @ rot.T + rng.normal(0.0, sigma, (n, 3))


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random proper rotation (3, 3)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotations (F, 3, 3) about a fixed unit axis by angles (F,) (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1 - c) * (k @ k)


@dataclass(frozen=True)
class FunctionalTrial:
    """parent (F, 4, 3) and child (F, 5, 3) noisy markers; centre_world (F, 3) the true joint centre;
    parent_clean (F, 4, 3) the noise-free parent markers (for the true centre in a marker-built frame)."""

    parent: np.ndarray
    child: np.ndarray
    centre_world: np.ndarray
    parent_clean: np.ndarray


def functional_trial(rng: np.random.Generator, amplitude_deg: float, noise_m: float, frames: int = 600,
                     parent_motion_deg: float = 10.0) -> FunctionalTrial:
    """A hip-like functional trial: a 4-marker pelvis moving in 6 DOF and a rigid 5-marker thigh cluster
    rotating about a ball joint by up to ±amplitude in flexion and abduction (Lissajous, so the cap is covered)
    plus a third of that about the thigh's long axis. Markers sit 0.1-0.45 m from the joint; metres."""
    t = np.linspace(0.0, 1.0, frames)
    amp = np.radians(amplitude_deg)
    pelvis_local = np.array([[0.12, 0.0, 0.05], [-0.12, 0.0, 0.05], [0.08, -0.15, 0.08], [-0.08, -0.15, 0.08]])
    joint_local = np.array([0.08, 0.02, -0.06])  # hip centre in the pelvis cluster's frame
    thigh_local = np.column_stack([rng.uniform(-0.06, 0.06, 5), rng.uniform(-0.06, 0.06, 5),
                                   -rng.uniform(0.1, 0.45, 5)])  # below the joint, along the thigh (−z)
    p_amp = np.radians(parent_motion_deg)
    parent_rot = (_axis_angle(np.array([1.0, 0, 0]), p_amp * np.sin(2 * np.pi * 1.3 * t))
                  @ _axis_angle(np.array([0, 0, 1.0]), p_amp * np.sin(2 * np.pi * 0.7 * t + 1.0)))
    parent_pos = np.column_stack([0.3 * t, 0.05 * np.sin(2 * np.pi * t), 0.9 + 0.02 * np.sin(4 * np.pi * t)])
    rel = (_axis_angle(np.array([1.0, 0, 0]), amp * np.sin(2 * np.pi * 3.0 * t))
           @ _axis_angle(np.array([0, 1.0, 0]), amp * np.sin(2 * np.pi * 2.0 * t + 0.5))
           @ _axis_angle(np.array([0, 0, 1.0]), amp / 3 * np.sin(2 * np.pi * 1.1 * t)))
    centre = parent_pos + np.einsum("fij,j->fi", parent_rot, joint_local)
    child_rot = parent_rot @ rel
    parent_clean = parent_pos[:, None] + np.einsum("fij,mj->fmi", parent_rot, pelvis_local)
    child_clean = centre[:, None] + np.einsum("fij,mj->fmi", child_rot, thigh_local)
    return FunctionalTrial(parent_clean + rng.normal(0, noise_m, parent_clean.shape),
                           child_clean + rng.normal(0, noise_m, child_clean.shape), centre, parent_clean)

