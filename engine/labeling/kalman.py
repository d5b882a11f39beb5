"""A bank of constant-velocity Kalman filters, one per marker label (paper 001 Eqs. 3-4), vectorised.

Why a 2x2 covariance per label instead of 6x6: with isotropic R = r²I, white-acceleration Q = q·Q₁ ⊗ I₃ and an
isotropic start, the three axes never couple, so P = P₂ ⊗ I₃ for all time. Keeping only P₂ (position/velocity
block of one axis) is exact, makes the innovation covariance a scalar S = P₂[0,0] + r², the Mahalanobis distance
|z − ẑ|²/S, and the gate a Euclidean ball of radius sqrt(γ S) — which a KD-tree answers directly.
"""
from __future__ import annotations

import numpy as np


class KalmanBank:
    """L independent constant-velocity filters. Positions in metres, velocities m/s, q in (m/s²)²."""

    def __init__(self, pos_m: np.ndarray, vel_mps: np.ndarray, accel_var: np.ndarray, meas_noise_m: float, dt_s: float):
        self.pos = np.asarray(pos_m, dtype=float).copy()  # (L,3)
        self.vel = np.asarray(vel_mps, dtype=float).copy()  # (L,3)
        self.accel_var = np.asarray(accel_var, dtype=float)  # (L,)
        self.r2 = float(meas_noise_m) ** 2
        self.dt = float(dt_s)
        n = len(self.pos)
        self.cov = np.zeros((n, 2, 2))  # per-axis [[var_p, cov_pv], [cov_pv, var_v]]
        self.cov[:, 0, 0] = self.r2
        self.cov[:, 1, 1] = 1.0  # (1 m/s)² prior on the velocity
        dt = self.dt
        self._f = np.array([[1.0, dt], [0.0, 1.0]])
        self._q1 = np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])

    def predict(self) -> None:
        """x⁻ = F x, P⁻ = F P Fᵀ + q_k Q₁."""
        self.pos += self.dt * self.vel
        self.cov = self._f @ self.cov @ self._f.T + self.accel_var[:, None, None] * self._q1

    def innovation_var(self) -> np.ndarray:
        """(L,) scalar innovation variance S = P⁻[0,0] + r² (the same on each axis)."""
        return self.cov[:, 0, 0] + self.r2

    def update(self, which: np.ndarray, z_m: np.ndarray, noise_scale: np.ndarray | float = 1.0) -> None:
        """Measurement update of the labels ``which`` (int indices) with positions z (n,3); R scaled per label."""
        if len(which) == 0:
            return
        cov = self.cov[which]
        s = cov[:, 0, 0] + self.r2 * np.broadcast_to(noise_scale, (len(which),))
        gain = cov[:, :, 0] / s[:, None]  # (n,2): position and velocity gains
        innov = z_m - self.pos[which]
        self.pos[which] += gain[:, :1] * innov
        self.vel[which] += gain[:, 1:] * innov
        self.cov[which] = cov - gain[:, :, None] * cov[:, None, 0, :]

    def restart(self, which: np.ndarray, z_m: np.ndarray, vel_std_mps: float = 2.0) -> None:
        """Start the filters ``which`` afresh at positions z (n,3): velocity 0 with a ``vel_std_mps`` prior.

        Used when a label is found again by shape far from where its filter predicted it; the open velocity
        prior widens the next gate so the marker is followed from the next frame on."""
        self.pos[which] = z_m
        self.vel[which] = 0.0
        self.cov[which] = np.array([[self.r2, 0.0], [0.0, vel_std_mps**2]])
