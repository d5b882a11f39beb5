"""Constant-velocity Kalman filter on the court plane (position m, velocity m/s).

Why constant velocity with white-noise acceleration: players accelerate hard but briefly; this model smooths
pixel noise in the ground point while following direction changes within a few frames, and it handles the
uneven frame intervals of a USB camera (dropped frames, jitter) because every step uses the real ``dt``.
"""
from __future__ import annotations

import numpy as np


class ConstantVelocityKalman:
    """State ``[x, y, vx, vy]``. ``accel_std_mps2``: process noise; ``measurement_std_m``: ground-point noise."""

    def __init__(self, accel_std_mps2: float = 6.0, measurement_std_m: float = 0.1) -> None:
        self.accel_var = accel_std_mps2**2
        self.meas_cov = np.eye(2) * measurement_std_m**2
        self.state: np.ndarray | None = None
        self.cov = np.eye(4)

    @property
    def initialised(self) -> bool:
        return self.state is not None

    def reset(self, position_m: np.ndarray) -> None:
        """Start a track at ``position_m`` with unknown velocity."""
        self.state = np.array([position_m[0], position_m[1], 0.0, 0.0])
        self.cov = np.diag([self.meas_cov[0, 0], self.meas_cov[1, 1], 4.0, 4.0])

    def predict(self, dt_s: float) -> None:
        """Advance by ``dt_s`` seconds (no-op before the first measurement)."""
        if self.state is None:
            return
        dt = max(float(dt_s), 0.0)
        f = np.eye(4)
        f[0, 2] = f[1, 3] = dt
        g = np.array([[dt**2 / 2, 0], [0, dt**2 / 2], [dt, 0], [0, dt]])
        self.state = f @ self.state
        self.cov = f @ self.cov @ f.T + self.accel_var * g @ g.T

    def innovation_distance_m(self, position_m: np.ndarray) -> float:
        """Euclidean distance (m) between a measurement and the predicted position."""
        assert self.state is not None
        return float(np.linalg.norm(np.asarray(position_m) - self.state[:2]))

    def update(self, position_m: np.ndarray) -> None:
        """Fuse one ground-point measurement (m)."""
        if self.state is None:
            self.reset(position_m)
            return
        h = np.zeros((2, 4))
        h[0, 0] = h[1, 1] = 1.0
        s = h @ self.cov @ h.T + self.meas_cov
        gain = self.cov @ h.T @ np.linalg.inv(s)
        self.state = self.state + gain @ (np.asarray(position_m) - h @ self.state)
        self.cov = (np.eye(4) - gain @ h) @ self.cov
