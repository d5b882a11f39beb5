"""Each worn segment's tilt from its accelerations, for posing (issue 18 item 3: accelerometer-only that listens).

Why: an accelerometer on a still or slowly moving segment reads +1 g along the world's up axis, i.e. the tilt of
the segment -- the same two degrees of freedom the tilt-only posing takes from an orientation quaternion
(orientation_pose.py: a swing about a horizontal axis is fixed by where "up" lies in the sensor frame). The search
plays database poses that may tilt a forearm 20 degrees wrong in a gesture the database lacks; the accelerations
say how it tilts now. While the segment accelerates the low-passed reading is not gravity, so each sensor's
share falls with its dynamic part (what the reading holds beyond the low-pass): full at rest, ~0.4 at
`STILL_G`, nothing in a swinging stride (measured: gestures held out 10.5 -> 9.2 cm, turning walks 5.3 -> 5.5 cm;
docs/engine-evaluation.md). Causal and per sample, so the batch search and the live decoder pose alike."""
from __future__ import annotations

import numpy as np

from engine.mocap import quaternions as quat

TIME_CONSTANT_S = 0.2  # the low-pass's memory (measured best of 0.03 / 0.1 / 0.2 / 0.5 / 1 s on held-out gestures)
STILL_G = 0.2  # the dynamic part (g) at which a sensor's share has fallen to exp(-1)
UP = np.array([0.0, 1.0, 0.0])


def tilt_quaternions(up_sensor: np.ndarray) -> np.ndarray:
    """(..., 4) sensor -> world rotations with no twist about the vertical that carry the sensor-frame
    directions `up_sensor` (..., 3) onto the world's up axis: the swing a tilt-only posing reads."""
    u = np.asarray(up_sensor, float)
    u = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-12)
    axis = np.cross(u, UP)
    sin = np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = np.arctan2(sin, (u @ UP)[..., None])
    return quat.from_rotvec(axis / np.maximum(sin, 1e-12) * angle)


class TiltFromAccelerations:
    """One sample at a time (`push`, in order): accelerations (S, 3) g -> (tilt quaternions (S, 4), shares (S,))."""

    def __init__(self, fps: float, time_constant_s: float = TIME_CONSTANT_S, still_g: float = STILL_G) -> None:
        self.alpha = 1.0 / (1.0 + time_constant_s * fps)  # the moving average's weight of each new sample
        self.still_g = still_g
        self._mean: np.ndarray | None = None  # low-passed accelerations (S, 3) g
        self._dynamic: np.ndarray | None = None  # low-passed |reading - low-pass| (S,) g

    def push(self, acc_g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """This sample's tilt estimates and shares (0 for a sensor whose reading is missing)."""
        acc = np.asarray(acc_g, float)
        ok = np.isfinite(acc).all(axis=-1)
        if self._mean is None:
            self._mean, self._dynamic = np.where(ok[:, None], acc, UP), np.zeros(len(acc))
        a = self.alpha
        self._mean = np.where(ok[:, None], self._mean + a * (acc - self._mean), self._mean)
        away = np.linalg.norm(np.where(ok[:, None], acc, self._mean) - self._mean, axis=-1)
        self._dynamic = self._dynamic + a * (away - self._dynamic)
        share = np.where(ok, np.exp(-(self._dynamic / self.still_g) ** 2), 0.0)
        return tilt_quaternions(self._mean), share
