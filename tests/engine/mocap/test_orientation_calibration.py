"""Calibrating orientation sensors from the still N-pose (engine/mocap/orientation_calibration.py, issue 18):
yaw offsets and strapping solved from readings made with known errors, on the shipped CMU clip and a Bandai
skeleton (raw, lying along X: the pose is built on its re-based frames)."""
from __future__ import annotations

import numpy as np
import pytest

import engine.mocap as M
from engine.mocap import quaternions as quat
from engine.mocap.orientation import random_rotations, to_device_earth, virtual_orientations
from engine.mocap.orientation_calibration import OrientationCalibration, mean_orientation, pose_sensor_orientations

NAMES = M.SEED000_SENSORS  # forearms, shins, lower back, chest
YAWS = np.array([2.0, -1.3, 0.4, 3.0, -2.5, 1.1])


def _angle_deg(a, b):
    return np.degrees(np.linalg.norm(quat.to_rotvec(quat.multiply(quat.conjugate(b), a)), axis=-1))


@pytest.fixture(scope="module")
def cmu():
    return M.load_clip(M.sample_clips()["16_16"])


def _skeletons(cmu):
    from bench.support.shared_data import find_shared_mocap

    out = {"cmu": cmu.skeleton}
    shared = find_shared_mocap()
    if shared is not None:
        out["bandai"] = M.read_bvh(shared / "bandai-namco-1/data/dataset-1_walk_normal_001.bvh").skeleton
    return out


def test_in_the_npose_limb_sensors_point_down_and_trunk_sensors_up(cmu):
    """Each standard sensor's x axis runs along its segment: down the forearms and shins, up the back."""
    for name, skeleton in _skeletons(cmu).items():
        x_world = quat.rotate(pose_sensor_orientations(skeleton, NAMES), np.array([1.0, 0.0, 0.0]))
        assert np.allclose(x_world[:4], [0.0, -1.0, 0.0], atol=0.05), (name, x_world)
        assert np.allclose(x_world[4:], [0.0, 1.0, 0.0], atol=0.1), (name, x_world)


def test_yaw_offsets_are_solved_exactly_from_a_held_pose(cmu):
    """No strapping error, the pose held exactly: the solved yaws are the devices' and `world` gives the true
    orientations of every later frame."""
    pose = pose_sensor_orientations(cmu.skeleton, NAMES, heading_rad=0.6)
    readings = to_device_earth(np.repeat(pose[None], 20, axis=0), YAWS)
    cal = OrientationCalibration.from_still_pose(readings, pose_sensor_orientations(cmu.skeleton, NAMES))
    heading_free = np.angle(np.exp(1j * (cal.yaw_rad - YAWS)))
    assert np.allclose(heading_free, heading_free[0], atol=1e-9)  # all off by the unknown heading, 0.6 rad
    true = virtual_orientations(cmu, M.standard_placements(cmu.skeleton))
    world = cal.world(to_device_earth(true, YAWS))
    relative = quat.multiply(M.orientation.yaw_about_up(heading_free[0]), world)
    assert _angle_deg(relative, true).max() < 1e-6


def test_strapping_errors_are_mostly_taken_out(cmu):
    """5 deg strapping errors: one pose cannot tell a turn about the vertical from yaw, so some error stays, but
    every later frame is closer to the truth than with the strapping ignored."""
    rng = np.random.default_rng(4)
    mount = random_rotations(rng, len(NAMES), np.radians(5.0))
    pose = pose_sensor_orientations(cmu.skeleton, NAMES)
    cal = OrientationCalibration.from_still_pose(to_device_earth(quat.multiply(pose, mount)[None], YAWS), pose)
    true = virtual_orientations(cmu, M.standard_placements(cmu.skeleton))
    readings = to_device_earth(quat.multiply(true, mount), YAWS)
    solved = _angle_deg(cal.world(readings), true)
    ignored = _angle_deg(OrientationCalibration(YAWS, np.tile([1.0, 0, 0, 0], (6, 1))).world(readings), true)
    assert solved.mean() < 0.5 * ignored.mean() and solved.max() < 5.0


def test_a_capture_with_gaps_or_the_wrong_shape_is_refused():
    pose = np.tile([1.0, 0.0, 0.0, 0.0], (6, 1))
    readings = np.repeat(pose[None], 5, axis=0)
    readings[2, 1] = np.nan
    with pytest.raises(ValueError, match="missing"):
        OrientationCalibration.from_still_pose(readings, pose)
    with pytest.raises(ValueError, match="expected readings"):
        OrientationCalibration.from_still_pose(readings[:, :4], pose)


def test_the_mean_of_a_still_capture_ignores_quaternion_sign():
    q = quat.normalize(np.array([[0.9, 0.1, 0.3, 0.2]]))
    frames = np.stack([q, -q, q])
    assert np.allclose(mean_orientation(frames), q, atol=1e-12)
