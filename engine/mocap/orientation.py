"""Virtual orientation sensors: what a real IMU's on-board fusion filter reports, simulated from mocap.

Why a module of its own: real IMUs (x-IMU3, Shimmer3, Xsens) stream an orientation quaternion beside the
accelerations, and in slow motion it carries what an accelerometer cannot (where a limb points around the
vertical). The engine, the emulated base stations and the evaluation must all simulate it the same way, with
the same frame conventions and the same error model, so they share this one definition.

Frames:

* engine world: Y up (docs/CONTRACTS.md);
* a device's **earth frame**: Z up, and a yaw that is arbitrary and *different per sensor* -- a
  magnetometer-free filter has no shared north, its yaw starts wherever the device booted and drifts;
* a quaternion ``q`` (w, x, y, z) maps sensor axes into the frame named: ``v_frame = rotate(q, v_sensor)``;
  the sensor axes are those of `engine.mocap.sensors.virtual_accelerometers`, so a still sensor's
  accelerometer reading is ``rotate(conj(q_world), up)`` in g.

``to_device_earth(q_world, yaw)`` = ``conj(EARTH_TO_WORLD) * yaw_about_up(yaw) * q_world``, and
``from_device_earth`` undoes the fixed Z-up -> Y-up change only: the per-sensor yaw stays in the result, because
nothing in one quaternion stream can tell it apart from the body's own heading. The engines deal with it
(features that do not need it, or an offset they estimate)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.mocap import quaternions as quat
from engine.mocap.sensors import SensorPlacement, _sensor_world
from engine.mocap.skeleton import Motion

# Device earth (x, y, z) with z up -> engine world (X, Y, Z) with Y up: earth z -> world Y, earth x -> world X,
# earth y -> world -Z (a proper rotation: -90 degrees about X).
EARTH_TO_WORLD = np.array([np.sqrt(0.5), -np.sqrt(0.5), 0.0, 0.0])


def yaw_about_up(yaw_rad: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) of rotations by ``yaw_rad`` about the engine world's up axis (+Y, counter-clockwise
    seen from above: the engine's heading convention)."""
    half = 0.5 * np.asarray(yaw_rad, float)
    zero = np.zeros_like(half)
    return np.stack([np.cos(half), zero, np.sin(half), zero], axis=-1)


def twist_yaw(quat_world: np.ndarray) -> np.ndarray:
    """(...,) rad: the rotation's twist about the world's up axis (+Y), q = yaw_about_up(ψ) * swing with the
    swing's axis horizontal; turning the frame by a yaw δ adds δ to ψ exactly."""
    q = np.asarray(quat_world, float)
    return 2.0 * np.arctan2(q[..., 2], q[..., 0])


def virtual_orientations(motion: Motion, placements: list[SensorPlacement],
                         fk: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """(F, S, 4) unit quaternions (w, x, y, z), sensor -> engine world, exact (no error): the orientation a perfect
    filter with a shared north aligned to the world would report."""
    _, r = _sensor_world(motion, placements, fk)
    return quat.canonical_sign(quat.from_matrix(r))


def to_device_earth(quat_world: np.ndarray, yaw_rad: np.ndarray | float = 0.0) -> np.ndarray:
    """Sensor -> engine world quaternions (..., 4) as a device reports them: in its Z-up earth frame whose yaw is
    turned by ``yaw_rad`` (broadcast against ``quat_world[..., 0]``; e.g. (S,) for one offset per sensor)."""
    q = np.asarray(quat_world, float)
    turned = quat.multiply(yaw_about_up(np.broadcast_to(yaw_rad, q.shape[:-1])), q)
    return quat.normalize(quat.multiply(quat.conjugate(EARTH_TO_WORLD), turned))


def from_device_earth(quat_device: np.ndarray) -> np.ndarray:
    """Device-earth (Z up) quaternions (..., 4) -> the engine's Y-up world, each still turned by its sensor's
    unknown yaw about the vertical."""
    return quat.normalize(quat.multiply(EARTH_TO_WORLD, np.asarray(quat_device, float)))


@dataclass(frozen=True)
class OrientationErrorModel:
    """What a real magnetometer-free orientation filter adds to the true sensor orientation (all per sensor).

    yaw_offset: each sensor's earth frame is turned by a random yaw, uniform on the circle (no shared north);
    north_spread_deg: None, or the sensors share one north (a magnetometer-aided filter: Xsens, Noitom, ...):
    one random yaw for all, each sensor's off it by this sd (the field's local disturbances);
    yaw_drift_deg_per_min: sd of each sensor's constant yaw drift rate (gyro bias the filter cannot see without a
    magnetometer); yaw_walk_deg_per_sqrt_min: sd of a random walk added on top of the drift (bias instability);
    tilt_noise_deg: sd of the tilt error, about a horizontal axis, correlated over ``tilt_time_constant_s`` (the
    filter's accelerometer correction is slow, so its tilt error wanders rather than jitters);
    misalignment_deg: sd of a constant random rotation between the sensor's axes and the placement's (strapping).

    The order of the errors: ``q_device = conj(E) * yaw(t) * tilt(t) * q_world * misalignment``."""

    yaw_offset: bool = True
    north_spread_deg: float | None = None
    yaw_drift_deg_per_min: float = 0.0
    yaw_walk_deg_per_sqrt_min: float = 0.0
    tilt_noise_deg: float = 0.0
    tilt_time_constant_s: float = 1.0
    misalignment_deg: float = 0.0

    @classmethod
    def realistic(cls) -> "OrientationErrorModel":
        """A consumer 6-axis IMU's on-board filter (no magnetometer): random yaw per sensor, drift of a few
        degrees a minute, 2 degrees of slowly wandering tilt error, 5 degrees of strapping misalignment."""
        return cls(yaw_offset=True, yaw_drift_deg_per_min=3.0, yaw_walk_deg_per_sqrt_min=1.0, tilt_noise_deg=2.0,
                   tilt_time_constant_s=1.0, misalignment_deg=5.0)

    @classmethod
    def magnetometer(cls) -> "OrientationErrorModel":
        """A 9-axis filter (magnetometer-aided, as Xsens MTw or DOT report by default): one north shared by every
        sensor, each 4 degrees (sd) off it where the court's steel bends the field, no drift, 1 degree of
        wandering tilt error, 5 degrees of strapping misalignment."""
        return cls(yaw_offset=True, north_spread_deg=4.0, yaw_walk_deg_per_sqrt_min=0.5, tilt_noise_deg=1.0,
                   tilt_time_constant_s=1.0, misalignment_deg=5.0)

    @classmethod
    def clean(cls) -> "OrientationErrorModel":
        """No error and a shared north aligned with the engine world: `apply` is then `to_device_earth`."""
        return cls(yaw_offset=False)

    def apply(self, quat_world: np.ndarray, fps: float, rng: np.random.Generator) -> np.ndarray:
        """Device-earth readings (F, S, 4) from true sensor -> world orientations (F, S, 4); deterministic for a
        given rng state (one `draw`, then `OrientationErrors.apply`)."""
        q = np.asarray(quat_world, float)
        return self.draw(q.shape[0], q.shape[1], fps, rng).apply(q)

    def draw(self, n_frames: int, n_sensors: int, fps: float, rng: np.random.Generator) -> "OrientationErrors":
        """One set of hardware's errors over `n_frames` frames at `fps`: what `apply` adds, kept so a test or an
        emulator knows the answer a calibration must find (each sensor's yaw offset at any frame)."""
        t_min = np.arange(n_frames) / fps / 60.0
        misalignment = random_rotations(rng, n_sensors, np.radians(self.misalignment_deg)) \
            if self.misalignment_deg > 0 else None
        tilt = self._tilt_errors(rng, n_frames, n_sensors, fps) if self.tilt_noise_deg > 0 else None
        yaw = np.zeros((n_frames, n_sensors))
        if self.yaw_offset and self.north_spread_deg is None:
            yaw += rng.uniform(-np.pi, np.pi, n_sensors)
        elif self.yaw_offset:
            yaw += rng.uniform(-np.pi, np.pi) + np.radians(rng.normal(0.0, self.north_spread_deg, n_sensors))
        if self.yaw_drift_deg_per_min > 0:
            yaw += np.radians(rng.normal(0.0, self.yaw_drift_deg_per_min, n_sensors)) * t_min[:, None]
        if self.yaw_walk_deg_per_sqrt_min > 0 and n_frames > 1:
            steps = rng.normal(0.0, 1.0, (n_frames, n_sensors)) * np.sqrt(1.0 / fps / 60.0)
            steps[0] = 0.0
            yaw += np.radians(self.yaw_walk_deg_per_sqrt_min) * np.cumsum(steps, axis=0)
        return OrientationErrors(yaw, tilt, misalignment)

    def _tilt_errors(self, rng: np.random.Generator, n_frames: int, n_sensors: int, fps: float) -> np.ndarray:
        """(F, S, 4) small rotations about horizontal world axes: two AR(1) angle processes per sensor (about X and
        Z) with stationary sd ``tilt_noise_deg`` and time constant ``tilt_time_constant_s``."""
        rho = float(np.exp(-1.0 / (fps * max(self.tilt_time_constant_s, 1e-9))))
        sd = np.radians(self.tilt_noise_deg)
        shocks = rng.normal(0.0, sd * np.sqrt(1.0 - rho**2), (n_frames, n_sensors, 2))
        angles = np.empty_like(shocks)
        angles[0] = rng.normal(0.0, sd, (n_sensors, 2))
        for f in range(1, n_frames):
            angles[f] = rho * angles[f - 1] + shocks[f]
        rotvec = np.stack([angles[..., 0], np.zeros((n_frames, n_sensors)), angles[..., 1]], axis=-1)
        return quat.from_rotvec(rotvec)


@dataclass(frozen=True)
class OrientationErrors:
    """One draw of `OrientationErrorModel`: ``yaw_rad`` (F, S) each sensor's earth-frame yaw per frame (offset,
    drift and walk), ``tilt_wxyz`` (F, S, 4) the filter's tilt error or None, ``misalignment_wxyz`` (S, 4) the
    strapping or None."""

    yaw_rad: np.ndarray
    tilt_wxyz: np.ndarray | None = None
    misalignment_wxyz: np.ndarray | None = None

    def apply(self, quat_world: np.ndarray) -> np.ndarray:
        """Device-earth readings (F, S, 4) of true sensor -> world orientations (F, S, 4):
        ``conj(E) * yaw(t) * tilt(t) * q_world * misalignment``."""
        q = np.asarray(quat_world, float)
        if self.misalignment_wxyz is not None:
            q = quat.multiply(q, self.misalignment_wxyz[None])
        if self.tilt_wxyz is not None:
            q = quat.multiply(self.tilt_wxyz, q)
        return quat.canonical_sign(to_device_earth(q, self.yaw_rad))


def random_rotations(rng: np.random.Generator, n: int, sd_rad: float) -> np.ndarray:
    """(n, 4) rotations about random axes by normally distributed angles (sd ``sd_rad``)."""
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return quat.from_rotvec(axes * rng.normal(0.0, sd_rad, n)[:, None])
