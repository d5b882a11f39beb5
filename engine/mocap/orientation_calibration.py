"""Calibrating orientation sensors from a still pose (issue 18): each sensor's yaw about the vertical and how it
is strapped to its segment.

Why: a magnetometer-free filter reports its orientation in an earth frame whose yaw is arbitrary and different
per sensor (engine/mocap/orientation.py), and every strap sits a few degrees off the nominal mounting. While the
athlete holds a known pose (the wizard's reference N-pose: engine.mocap.calibration_poses) each sensor's nominal
orientation P is known, and its reading Q = yaw(δ) P M (earth yaw δ, strapping M) gives both: δ = the twist
about the vertical of Q P⁻¹ (one pose cannot split a turn about the vertical between δ and M; the part that
could be either goes to δ, so M is the smallest strapping rotation that explains the reading), then
M = P⁻¹ yaw(-δ) Q. Afterwards ``world(q)`` = yaw(-δ) Q M⁻¹ is the segment's nominal sensor orientation in the
world, up to the filter's drift since the capture and the athlete's imprecision in holding the pose.

The heading the athlete faces during the capture is shared by every sensor, and the engines use each sensor's
yaw relative to the pelvis sensor, so it need not be known (default 0)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.mocap import quaternions as quat
from engine.mocap.calibration_poses import pose_rotations
from engine.mocap.orientation import from_device_earth, twist_yaw, yaw_about_up
from engine.mocap.rest_pose import tpose_skeleton
from engine.mocap.sensors import standard_placements
from engine.mocap.skeleton import Skeleton


def mean_orientation(quat_wxyz: np.ndarray) -> np.ndarray:
    """(S, 4) the mean of (F, S, 4) unit quaternions close to each other (a still capture): signs aligned to the
    first frame, summed, normalised."""
    q = np.asarray(quat_wxyz, float)
    sign = np.sign(np.sum(q * q[:1], axis=-1, keepdims=True))
    return quat.normalize((q * np.where(sign == 0, 1.0, sign)).sum(axis=0))


def pose_sensor_orientations(skeleton: Skeleton, sensor_names: list[str] | tuple[str, ...], pose: str = "npose",
                             heading_rad: float = 0.0, arm_deg: float | None = None) -> np.ndarray:
    """(S, 4) sensor -> world orientations of the named standard sensors while `skeleton` holds the calibration
    `pose` (an A-pose with the arms `arm_deg` out), facing `heading_rad`. The pose is built on the T-pose re-based
    skeleton (the same bones in frames whose zero pose is upright), so raw Bandai skeletons work too."""
    upright = tpose_skeleton(skeleton)
    glob = pose_rotations(upright, pose, arm_deg)
    placements = standard_placements(upright, list(sensor_names))
    mats = np.stack([glob[p.joint] @ p.rotation for p in placements])
    return quat.canonical_sign(quat.multiply(yaw_about_up(heading_rad), quat.from_matrix(mats)))


@dataclass(frozen=True)
class OrientationCalibration:
    """Per sensor: ``yaw_rad`` (S,) its earth frame's yaw about the world vertical, ``mount_wxyz`` (S, 4) its
    strapping (sensor axes -> the segment's nominal sensor frame, right-multiplied)."""

    yaw_rad: np.ndarray
    mount_wxyz: np.ndarray

    @classmethod
    def from_still_pose(cls, quat_device: np.ndarray, pose_world: np.ndarray) -> "OrientationCalibration":
        """Solve from device-earth readings (F, S, 4) taken while the athlete held a pose whose nominal sensor
        orientations are `pose_world` (S, 4) (`pose_sensor_orientations`)."""
        q = np.asarray(quat_device, float)
        if q.ndim != 3 or q.shape[1:] != np.shape(pose_world) or q.shape[-1] != 4 or not len(q):
            raise ValueError(f"expected readings (frames, {len(pose_world)}, 4), got {q.shape}")
        if not np.isfinite(q).all():
            raise ValueError("the calibration capture holds missing orientation readings")
        observed = from_device_earth(mean_orientation(q))
        pose = np.asarray(pose_world, float)
        yaw = twist_yaw(quat.multiply(observed, quat.conjugate(pose)))
        mount = quat.multiply(quat.conjugate(pose), quat.multiply(yaw_about_up(-yaw), observed))
        return cls(yaw, quat.canonical_sign(mount))

    def select(self, indices: list[int] | tuple[int, ...]) -> "OrientationCalibration":
        """The calibration of a subset of the sensors (in `indices` order)."""
        idx = list(indices)
        return OrientationCalibration(np.asarray(self.yaw_rad)[idx], np.asarray(self.mount_wxyz)[idx])

    def world(self, quat_device: np.ndarray) -> np.ndarray:
        """(..., S, 4) device-earth readings -> the segments' nominal sensor orientations in the world."""
        q = from_device_earth(np.asarray(quat_device, float))
        return quat.multiply(quat.multiply(yaw_about_up(-self.yaw_rad), q), quat.conjugate(self.mount_wxyz))
