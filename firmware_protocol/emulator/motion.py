"""What the emulated sensors feel: a `MotionSource` maps true times to per-sensor acceleration in g; an
`OrientationSource` also gives what each sensor's on-board fusion filter reports (a quaternion sensor -> the
device's own earth frame, Z up, yaw per sensor) and its gyroscope (rad/s, sensor frame).

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


@runtime_checkable
class OrientationSource(MotionSource, Protocol):
    def orientation_wxyz(self, times_s: np.ndarray) -> np.ndarray:
        """(len(times_s), n_sensors, 4) unit quaternions sensor -> device earth (Z up), as the filter reports."""
        ...

    def angular_rate_rps(self, times_s: np.ndarray) -> np.ndarray:
        """(len(times_s), n_sensors, 3) angular rate, rad/s, sensor frame."""
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
        self.orientations_wxyz = orientations_wxyz

    def acceleration_g(self, times_s: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self.reading_g, (len(times_s), self.n_sensors, 3)).copy()

    def orientation_wxyz(self, times_s: np.ndarray) -> np.ndarray:
        """A perfect filter whose earth frame is the world's turned to Z up (no yaw error: nothing moves)."""
        from engine.mocap.orientation import to_device_earth  # lazy: only an orientation station needs it

        return np.broadcast_to(to_device_earth(self.orientations_wxyz), (len(times_s), self.n_sensors, 4)).copy()

    def angular_rate_rps(self, times_s: np.ndarray) -> np.ndarray:
        return np.zeros((len(times_s), self.n_sensors, 3))


class TraceSource:
    """A recorded (F, S, 3) trace in g at `fps`, linearly interpolated and looped (last frame blends into the first);
    optionally with device-earth orientations ``quat_wxyz`` (F, S, 4) and angular rates ``gyro_rps`` (F, S, 3) of
    the same frames (then it is an `OrientationSource`)."""

    def __init__(self, acc_g: np.ndarray, fps: float, quat_wxyz: np.ndarray | None = None,
                 gyro_rps: np.ndarray | None = None) -> None:
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
        for name, extra, width in (("quat_wxyz", quat_wxyz, 4), ("gyro_rps", gyro_rps, 3)):
            if extra is not None and (np.shape(extra) != acc_g.shape[:2] + (width,) or not np.isfinite(extra).all()):
                raise ValueError(f"{name} must be finite ({acc_g.shape[0]}, {acc_g.shape[1]}, {width}), "
                                 f"got {np.shape(extra)}")
        # orientation interpolates component-wise between sign-aligned neighbours, then renormalises (nlerp:
        # indistinguishable from slerp between mocap frames 1/60 s apart)
        self.quat_wxyz = None if quat_wxyz is None else _sign_continuous(np.asarray(quat_wxyz, np.float64))
        self.gyro_rps = None if gyro_rps is None else np.asarray(gyro_rps, np.float64)

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
        return self._interpolate(self.acc_g, times_s)

    @property
    def streams_orientation(self) -> bool:
        """Whether this trace can drive an orientation station (it has both extra channels)."""
        return self.quat_wxyz is not None and self.gyro_rps is not None

    def orientation_wxyz(self, times_s: np.ndarray) -> np.ndarray:
        if self.quat_wxyz is None:
            raise ValueError("this trace has no orientation")
        q0, q1, frac = self._neighbours(self.quat_wxyz, times_s)
        q1 = np.where((np.sum(q0 * q1, axis=-1) < 0)[..., None], -q1, q1)  # the loop's wrap may flip the sign
        q = q0 * (1.0 - frac) + q1 * frac
        return q / np.linalg.norm(q, axis=-1, keepdims=True)

    def angular_rate_rps(self, times_s: np.ndarray) -> np.ndarray:
        if self.gyro_rps is None:
            raise ValueError("this trace has no angular rate")
        return self._interpolate(self.gyro_rps, times_s)

    def _neighbours(self, values: np.ndarray, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        f = np.asarray(times_s, dtype=np.float64) * self.fps
        i0 = np.floor(f)
        frac = (f - i0)[:, None, None]
        n = values.shape[0]
        i0 = i0.astype(np.int64) % n
        return values[i0], values[(i0 + 1) % n], frac

    def _interpolate(self, values: np.ndarray, times_s: np.ndarray) -> np.ndarray:
        v0, v1, frac = self._neighbours(values, times_s)
        return v0 * (1.0 - frac) + v1 * frac


def _sign_continuous(q: np.ndarray) -> np.ndarray:
    """Quaternions (F, S, 4) with each frame's sign flipped to agree with the previous frame's (q and -q are the
    same rotation; interpolating across a flip would pass through zero)."""
    q = q.copy()
    for f in range(1, len(q)):
        flip = np.sum(q[f] * q[f - 1], axis=-1) < 0
        q[f, flip] *= -1
    return q


class MocapSource(TraceSource):
    """Virtual accelerometers on a mocap clip (engine.mocap), played as a looping trace."""

    @classmethod
    def from_clip(cls, path_or_motion: Any, placements: Any = None, orientation_seed: int | None = None
                  ) -> MocapSource:
        """`path_or_motion`: a .bvh / .amc (sibling .asf) path or an engine.mocap.Motion; `placements`:
        SensorPlacement list or sensor names for `standard_placements` (default: the engine's seed-000 six).
        ``orientation_seed``: also simulate each sensor's orientation filter (the realistic error model, this
        seed) and gyroscope."""
        from engine import mocap  # lazy: the emulator must not need the engine unless a mocap source is used

        motion = mocap.load_clip(path_or_motion) if isinstance(path_or_motion, (str, Path)) else path_or_motion
        if placements is None:
            placements = mocap.standard_placements(motion.skeleton)
        elif all(isinstance(p, str) for p in placements):
            placements = mocap.standard_placements(motion.skeleton, list(placements))
        quat = gyro = None
        if orientation_seed is not None:
            quat, gyro = device_orientations(motion, placements, np.random.default_rng(orientation_seed))
        return cls(mocap.virtual_accelerometers(motion, placements), motion.fps, quat, gyro)


def device_orientations(motion: Any, placements: Any, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """What worn real IMUs would report on ``motion``: device-earth quaternions (F, S, 4) through
    `OrientationErrorModel.realistic()` (random yaw per sensor, yaw drift, tilt noise, misalignment) and exact
    angular rates (F, S, 3) rad/s from `virtual_gyroscopes`."""
    from engine import mocap
    from engine.mocap.orientation import OrientationErrorModel, virtual_orientations

    world = virtual_orientations(motion, placements)
    return (OrientationErrorModel.realistic().apply(world, motion.fps, rng),
            mocap.virtual_gyroscopes(motion, placements))
