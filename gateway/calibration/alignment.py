"""Gravity alignment and accelerometer checks from still data.

Sensor-to-segment rotation ``R`` (sensor axes -> segment frame, what ``engine.mocap.SensorPlacement.rotation``
takes). A still sensor reads the specific force ``+1 g`` along world up, so its mean reading ``g_s`` (sensor frame)
must satisfy ``R @ g_s = up_seg``, the segment's up direction in the pose (segment frame).

Yaw ambiguity: one gravity direction fixes only 2 of the 3 rotation angles; any rotation about ``up_seg`` also
fits. We resolve it by assumption: the sensor is mounted with its *nominal* orientation (from the placement
table, e.g. ``engine.mocap.standard_placements``) up to a tilt. ``R`` is the nominal rotation followed by the
smallest rotation that takes the nominal prediction of up onto the measured one. A mounting error about the
segment's vertical axis is therefore not corrected (documented; a second pose with a different segment
inclination resolves it, :func:`rotation_from_directions` accepts several pose pairs).
"""
from __future__ import annotations

import numpy as np

from engine.mocap.rotations import best_rotation, minimal_rotation

UP = np.array([0.0, 1.0, 0.0])


def _unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def sensor_to_segment_rotation(gravity_sensor: np.ndarray, nominal_rotation: np.ndarray,
                               expected_up: np.ndarray = UP) -> np.ndarray:
    """``R`` (sensor -> segment) from the still mean reading ``gravity_sensor`` (3,), the nominal mounting
    ``nominal_rotation`` (3, 3) and the segment's up direction in the pose ``expected_up`` (segment frame)."""
    nominal = np.asarray(nominal_rotation, float)
    return minimal_rotation(nominal @ _unit(gravity_sensor), expected_up) @ nominal


def rotation_from_directions(sensor_dirs: np.ndarray, segment_dirs: np.ndarray) -> np.ndarray:
    """Least-squares rotation ``R`` with ``R @ sensor_dirs[k] ~ segment_dirs[k]`` (Kabsch/Wahba) from >= 2
    non-parallel pairs, e.g. the up direction in two poses with different segment inclinations."""
    a, b = _unit(np.asarray(sensor_dirs, float)), _unit(np.asarray(segment_dirs, float))
    if len(a) < 2 or np.linalg.matrix_rank(a, tol=1e-3) < 2:
        raise ValueError("need at least two non-parallel direction pairs to fix all three rotation angles")
    return best_rotation(a, b)


def rotation_angle_deg(r: np.ndarray) -> float:
    """Angle (degrees) of a rotation matrix (e.g. of ``R_est @ R_true.T`` for an error)."""
    return float(np.degrees(np.arccos(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0))))


def tilt_deg(acc_g: np.ndarray, nominal_rotation: np.ndarray, expected_up: np.ndarray = UP) -> float:
    """Angle (degrees) between where the nominally mounted sensor says up is and where it should be: the
    placement check (small = mounted as expected; ~180 = upside down)."""
    predicted = np.asarray(nominal_rotation, float) @ _unit(acc_g)
    return float(np.degrees(np.arccos(np.clip(predicted @ _unit(expected_up), -1.0, 1.0))))


def norm_error_g(mean_acc_g: np.ndarray) -> float:
    """``|mean a| - 1 g`` of a still period: the bias/scale health check (GGIR-style). With one pose it sees the
    bias component along gravity (plus scale error); a full 3-axis offset needs several orientations."""
    return float(np.linalg.norm(mean_acc_g) - 1.0)


def fit_offset_g(still_means_g: np.ndarray) -> np.ndarray:
    """Accelerometer offset (3,) g from the mean readings (K, 3) of K >= 4 still periods in different
    orientations (tumble or natural pauses): the ``b`` that puts every ``m_k - b`` on the 1 g sphere.

    Linear least squares on ``2 m_k . b + (1 - |b|^2) = |m_k|^2`` (unknowns ``b`` and ``c = 1 - |b|^2``)."""
    m = np.asarray(still_means_g, float)
    centred = m - m.mean(axis=0)
    if len(m) < 4 or np.linalg.matrix_rank(centred, tol=0.2) < 3:
        raise ValueError("need >= 4 still orientations spread in all three axes to fit a 3-axis offset")
    design = np.column_stack([2.0 * m, np.ones(len(m))])
    solution, *_ = np.linalg.lstsq(design, np.sum(m**2, axis=1), rcond=None)
    return solution[:3]
