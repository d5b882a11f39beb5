"""Which IMU channels the OLNG searches on, and the yaw-free features it takes from them (issue 18).

A real IMU streams, beside its accelerations, an orientation quaternion (sensor -> the device's own earth frame,
Z up, yaw arbitrary and different per sensor: docs/CONTRACTS.md) and an angular rate in the sensor frame. The
OLNG uses only what survives the unknown per-sensor yaw:

* ``orientation`` -> the sensor's **tilt**: the up direction in the sensor's own axes (a unit vector). A yaw
  about the vertical does not change it, so the device's arbitrary north drops out. It is the gravity part of an
  accelerometer reading without the linear acceleration (a still sensor reads exactly its up vector, in g).
* ``gyro`` -> the angular rate in the sensor frame (rad/s), also independent of any earth frame.

The search vector is ``[acc_g, tilt_weight * up, gyro_weight_s * gyro]`` per sensor block. Weights: the tilt is
in g-equivalent units already (weight 1: the same footing as the acceleration it cleans up); ``gyro_weight_s``
turns rad/s into g (0.1 s: a limb turning at 5 rad/s weighs like a 0.5 g acceleration difference; swept in
docs/engine-olng-hmm.md). With accelerations only the vector is the paper's 12-D reading, unchanged."""
from __future__ import annotations

import numpy as np

from engine.mocap import quaternions as quat

CHANNELS = ("acc", "orientation", "gyro")
_EARTH_UP = np.array([0.0, 0.0, 1.0])   # device earth: Z up
_WORLD_UP = np.array([0.0, 1.0, 0.0])   # engine world: Y up


def tilt_from_device_earth(quat_wxyz: np.ndarray) -> np.ndarray:
    """(..., 4) sensor -> device-earth quaternions -> (..., 3) up direction in sensor axes (yaw-free)."""
    return quat.rotate(quat.conjugate(quat.normalize(np.asarray(quat_wxyz, float))), _EARTH_UP)


def tilt_from_world(quat_world: np.ndarray) -> np.ndarray:
    """(..., 4) sensor -> engine-world quaternions (`engine.mocap.orientation.virtual_orientations`) -> up in
    sensor axes: the same feature the database is built from."""
    return quat.rotate(quat.conjugate(np.asarray(quat_world, float)), _WORLD_UP)


def check_channels(channels: tuple[str, ...]) -> tuple[str, ...]:
    """Channels in canonical order; acc is always searched on (the energy's control term reads it)."""
    unknown = set(channels) - set(CHANNELS)
    if unknown or "acc" not in channels:
        raise ValueError(f"OLNG channels must include 'acc' and be among {CHANNELS}, got {channels}")
    return tuple(c for c in CHANNELS if c in channels)


def search_vector(channels: tuple[str, ...], acc_g: np.ndarray, tilt: np.ndarray | None, gyro_rps: np.ndarray | None,
                  tilt_weight: float, gyro_weight_s: float) -> np.ndarray:
    """Per-frame search features (..., S*3*len(channels)) from (..., S, 3) blocks, channel-major."""
    parts = [np.asarray(acc_g, float)]
    if "orientation" in channels:
        parts.append(tilt_weight * np.asarray(tilt, float))
    if "gyro" in channels:
        parts.append(gyro_weight_s * np.asarray(gyro_rps, float))
    lead = parts[0].shape[:-2]
    return np.concatenate([p.reshape(lead + (-1,)) for p in parts], axis=-1)
