"""Relative yaw between worn sensors, with each device's unknown yaw offset estimated online (issue 18).

WHY: in slow motion an accelerometer (and the tilt of an orientation) sees how a segment leans, not where it
points around the vertical; the orientation quaternion does know that, but in the device's own earth frame whose
north is arbitrary and different per sensor. The yaw of sensor s relative to a reference sensor (column 0),
rho_s = psi_s - psi_0, is body-intrinsic up to one constant per sensor, o_s (the difference of the two devices'
norths; it drifts by a few degrees a minute). The database knows the true rho of every frame. So each frame, after
the search, the measured rho minus the rho of the chosen hypotheses (Eq. 1 weights, a circular mean) is a sample
of o_s; an exponentially forgetting circular mean (`time_constant_s`) estimates it. Once the estimate is steady
(resultant length >= `min_resultant`, after `min_frames` = `NeighbourhoodGraphConfig.yaw_min_frames`), every candidate's node distance gains
``yaw_weight * |exp(i rho_db) - exp(i (rho_meas - o))|`` per sensor, so the search can tell apart poses whose
segments lean alike but point differently.

psi is the twist about the vertical of the sensor -> earth rotation (swing-twist split), so a yaw offset of the
earth frame adds to it exactly.
"""
from __future__ import annotations

import numpy as np

from engine.mocap.orientation import to_device_earth


def device_yaw(quat_wxyz: np.ndarray) -> np.ndarray:
    """(..., 4) sensor -> device-earth (Z up) quaternions -> (...,) twist about the vertical (rad)."""
    q = np.asarray(quat_wxyz, float)
    return 2.0 * np.arctan2(q[..., 3], q[..., 0])


def relative_yaw(yaw_rad: np.ndarray) -> np.ndarray:
    """(..., S) yaws -> (..., S-1) yaw of sensors 1.. relative to sensor 0, as unit complex numbers."""
    return np.exp(1j * (yaw_rad[..., 1:] - yaw_rad[..., :1]))


def database_relative_yaw(quat_world: np.ndarray) -> np.ndarray:
    """(N, S, 4) true sensor -> world quaternions -> (N, S-1) complex relative yaw (aligned device norths)."""
    return relative_yaw(device_yaw(to_device_earth(quat_world, 0.0)))


class YawOffsets:
    """Online estimate of each sensor's yaw offset relative to sensor 0, and the yaw term of the search."""

    def __init__(self, database_rel: np.ndarray, fps: float, yaw_weight: float, time_constant_s: float = 20.0,
                 min_frames: int = 10, min_resultant: float = 0.7) -> None:
        self.db = database_rel                     # (N, S-1) complex
        self.weight = yaw_weight
        self.forget = 1.0 - 1.0 / max(time_constant_s * fps, 1.0)
        self.min_frames, self.min_resultant = min_frames, min_resultant
        self._sum = np.zeros(database_rel.shape[1], complex)
        self._mass = 0.0
        self.frames = 0
        self._rel: np.ndarray | None = None        # this frame's measured relative yaw

    @property
    def ready(self) -> bool:
        return (self.frames >= self.min_frames and self._mass > 0
                and bool(np.all(np.abs(self._sum) / self._mass >= self.min_resultant)))

    @property
    def offsets_rad(self) -> np.ndarray:
        return np.angle(self._sum)

    def observe(self, quat_wxyz: np.ndarray | None) -> None:
        """This frame's device quaternions (S, 4); None / NaN keeps the previous frame's measurement."""
        if quat_wxyz is not None and np.all(np.isfinite(quat_wxyz)):
            self._rel = relative_yaw(device_yaw(quat_wxyz))

    def distances(self, idx: np.ndarray, dist: np.ndarray) -> np.ndarray:
        """Node distances of the candidates ``idx`` with the yaw term added (unchanged until `ready`)."""
        if self._rel is None or not self.ready:
            return dist
        corrected = self._rel * np.exp(-1j * self.offsets_rad)
        yaw = np.abs(self.db[idx] - corrected[None]).sum(axis=1)
        return np.sqrt(dist**2 + (self.weight * yaw) ** 2)

    def update(self, nodes: np.ndarray, weights: np.ndarray) -> None:
        """Fold in this frame's offset sample: measured relative yaw against the chosen hypotheses'."""
        if self._rel is None:
            return
        db = weights @ self.db[nodes]                  # weighted circular mean (unnormalised)
        sample = self._rel * np.conj(db / np.maximum(np.abs(db), 1e-12))
        self._sum = self.forget * self._sum + sample
        self._mass = self.forget * self._mass + 1.0
        self.frames += 1
