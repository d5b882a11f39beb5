"""What the emulated sensors feel: a `MotionSource` maps true times to per-sensor acceleration in g.

Sensors measure specific force in their own frame, so a sensor lying still reads +1 g along the axis that
points up (engine world frame: Y up).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from engine.array_checks import load_npy

GRAVITY_UP_WORLD = np.array([0.0, 1.0, 0.0])


@runtime_checkable
class MotionSource(Protocol):
    n_sensors: int

    def acceleration_g(self, times_s: np.ndarray) -> np.ndarray:
        """(len(times_s), n_sensors, 3) specific force in g, sensor frame."""
        ...


def _quaternion_matrices(q_wxyz: np.ndarray) -> np.ndarray:
    q = np.asarray(q_wxyz, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


class StillSource:
    """Sensors lying still: each reads gravity rotated into its frame (calibration-pose tests).

    `orientations_wxyz` (S, 4): sensor-to-world rotation of every sensor; identity = sensor Y points up."""

    def __init__(self, n_sensors: int = 6, orientations_wxyz: np.ndarray | None = None) -> None:
        if orientations_wxyz is None:
            orientations_wxyz = np.tile([1.0, 0.0, 0.0, 0.0], (n_sensors, 1))
        orientations_wxyz = np.asarray(orientations_wxyz, dtype=np.float64)
        if orientations_wxyz.shape != (n_sensors, 4):
            raise ValueError(f"orientations must be ({n_sensors}, 4) quaternions, got {orientations_wxyz.shape}")
        self.n_sensors = n_sensors
        # world -> sensor is the transpose of sensor -> world
        self.reading_g = np.einsum("sji,j->si", _quaternion_matrices(orientations_wxyz), GRAVITY_UP_WORLD)

    def acceleration_g(self, times_s: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self.reading_g, (len(times_s), self.n_sensors, 3)).copy()


class TraceSource:
    """A recorded (F, S, 3) trace in g at `fps`, linearly interpolated and looped (last frame blends into the first)."""

    def __init__(self, acc_g: np.ndarray, fps: float) -> None:
        acc_g = np.asarray(acc_g, dtype=np.float64)
        if acc_g.ndim != 3 or acc_g.shape[2] != 3 or acc_g.shape[0] < 1:
            raise ValueError(f"trace must be (frames, sensors, 3), got {acc_g.shape}")
        if not np.all(np.isfinite(acc_g)):
            raise ValueError("trace contains NaN or infinite values")
        if fps <= 0:
            raise ValueError(f"fps must be positive, got {fps}")
        self.acc_g = acc_g
        self.fps = float(fps)
        self.n_sensors = acc_g.shape[1]

    @property
    def duration_s(self) -> float:
        return self.acc_g.shape[0] / self.fps

    @classmethod
    def from_npy(cls, path: str | Path, fps: float) -> TraceSource:
        """Load an (F, S, 3) g trace saved with numpy.save; errors name the file."""
        acc = load_npy(path, "trace")
        try:
            return cls(acc, fps)
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from exc

    def acceleration_g(self, times_s: np.ndarray) -> np.ndarray:
        f = np.asarray(times_s, dtype=np.float64) * self.fps
        i0 = np.floor(f)
        frac = (f - i0)[:, None, None]
        n = self.acc_g.shape[0]
        i0 = i0.astype(np.int64) % n
        return self.acc_g[i0] * (1.0 - frac) + self.acc_g[(i0 + 1) % n] * frac


class MocapSource(TraceSource):
    """Virtual accelerometers on a mocap clip (engine.mocap), played as a looping trace."""

    @classmethod
    def from_clip(cls, path_or_motion: Any, placements: Any = None) -> MocapSource:
        """`path_or_motion`: a .bvh / .amc (sibling .asf) path or an engine.mocap.Motion; `placements`:
        SensorPlacement list or sensor names for `standard_placements` (default: the engine's seed-000 six)."""
        from engine import mocap  # lazy: the emulator must not need the engine unless a mocap source is used

        motion = mocap.load_clip(path_or_motion) if isinstance(path_or_motion, (str, Path)) else path_or_motion
        if placements is None:
            placements = mocap.standard_placements(motion.skeleton)
        elif all(isinstance(p, str) for p in placements):
            placements = mocap.standard_placements(motion.skeleton, list(placements))
        return cls(mocap.virtual_accelerometers(motion, placements), motion.fps)
