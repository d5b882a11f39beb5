"""Virtual orientation sensors and their error model against exact answers."""
from dataclasses import replace

import numpy as np

import engine.mocap as M
from engine.mocap import quaternions as quat
from engine.mocap.orientation import (EARTH_TO_WORLD, OrientationErrorModel, from_device_earth, to_device_earth,
                                      virtual_orientations, yaw_about_up)
from engine.mocap.sensors import UP

RNG_SEED = 7


def _walk() -> tuple[M.Motion, list[M.SensorPlacement]]:
    motion = M.load_clip(M.sample_clips()["16_16"], fps=30)
    return motion, M.standard_placements(motion.skeleton)


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between rotations a and b (..., 4), degrees."""
    d = np.abs(np.sum(quat.normalize(a) * quat.normalize(b), axis=-1))
    return np.degrees(2 * np.arccos(np.clip(d, 0, 1)))


def test_earth_to_world_takes_device_up_to_engine_up_and_keeps_handedness():
    m = quat.to_matrix(EARTH_TO_WORLD)
    np.testing.assert_allclose(m @ [0, 0, 1], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(m @ [1, 0, 0], [1, 0, 0], atol=1e-12)
    assert np.isclose(np.linalg.det(m), 1.0)


def test_yaw_about_up_turns_forward_counter_clockwise_seen_from_above():
    fwd = quat.rotate(yaw_about_up(np.pi / 2), np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(fwd, [1, 0, 0], atol=1e-12)  # heading = atan2(x, z) = +90 degrees


def test_orientations_agree_with_the_accelerometers_and_gyros_of_the_same_sensors():
    motion, placements = _walk()
    q = virtual_orientations(motion, placements)
    assert q.shape == (motion.n_frames, len(placements), 4)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-12)
    # gravity seen in each sensor frame = the mean accelerometer reading over a clip (the dynamic part averages
    # out over a walk cycle to within a few hundredths of a g)
    acc = M.virtual_accelerometers(motion, placements)
    up_in_sensor = quat.rotate(quat.conjugate(q), np.broadcast_to(UP, q.shape[:-1] + (3,)))
    gap = np.linalg.norm(acc.mean(axis=0) - up_in_sensor.mean(axis=0), axis=-1)
    assert gap.max() < 0.15
    # the central-difference gyro of the quaternions is the virtual gyroscope
    rel = quat.multiply(quat.conjugate(q[:-2]), q[2:])
    gyro = quat.to_rotvec(rel) * motion.fps / 2
    np.testing.assert_allclose(gyro, M.virtual_gyroscopes(motion, placements)[1:-1], atol=1e-9)


def test_device_earth_round_trip_keeps_the_per_sensor_yaw_and_nothing_else():
    motion, placements = _walk()
    q = virtual_orientations(motion, placements)
    yaw = np.linspace(-3, 3, len(placements))
    back = from_device_earth(to_device_earth(q, yaw))
    np.testing.assert_allclose(_angle_deg(back, quat.multiply(yaw_about_up(yaw), q)), 0, atol=1e-5)


def test_clean_model_is_exactly_the_world_orientation_in_device_axes():
    motion, placements = _walk()
    q = virtual_orientations(motion, placements)
    dev = OrientationErrorModel.clean().apply(q, motion.fps, np.random.default_rng(RNG_SEED))
    np.testing.assert_allclose(_angle_deg(from_device_earth(dev), q), 0, atol=1e-5)
    # the device frame is Z up: a sensor's gravity direction comes out along earth +Z
    up_dev = quat.rotate(dev, quat.rotate(quat.conjugate(q), np.broadcast_to(UP, q.shape[:-1] + (3,))))
    np.testing.assert_allclose(up_dev, np.broadcast_to([0, 0, 1.0], up_dev.shape), atol=1e-9)


def test_realistic_model_has_random_yaws_small_tilt_and_drift_of_the_stated_size():
    motion, placements = _walk()
    q = np.repeat(virtual_orientations(motion, placements)[:1], 60 * 30, axis=0)  # one minute standing still
    model = OrientationErrorModel.realistic()
    dev = model.apply(q, 30.0, np.random.default_rng(RNG_SEED))
    world = from_device_earth(dev)
    # tilt error: angle between the true and reported up vector in the sensor frame
    up = np.broadcast_to(UP, q.shape[:-1] + (3,))
    true_up = quat.rotate(quat.conjugate(q), up)
    seen_up = quat.rotate(quat.conjugate(world), up)
    tilt_deg = np.degrees(np.arccos(np.clip(np.sum(true_up * seen_up, axis=-1), -1, 1)))
    assert 1.0 < np.sqrt(np.mean(tilt_deg**2)) < 12.0  # 2 deg per axis + 5 deg misalignment, well under 12
    # yaw of each sensor relative to the truth (the yaw terms alone, so the error rotation is a pure yaw):
    # spread over the circle, slowly varying over the minute
    yaw_only = replace(model, tilt_noise_deg=0.0, misalignment_deg=0.0)
    err = quat.multiply(from_device_earth(yaw_only.apply(q, 30.0, np.random.default_rng(RNG_SEED))),
                        quat.conjugate(q))
    np.testing.assert_allclose(err[..., [1, 3]], 0, atol=1e-9)  # no tilt left in it
    offset = 2 * np.arctan2(err[..., 2], err[..., 0])
    assert np.ptp(np.angle(np.exp(1j * offset[0]))) > np.radians(60)  # six sensors do not share a north
    change = np.degrees(np.abs(np.angle(np.exp(1j * (offset[-1] - offset[0])))))
    assert 0.1 < change.max() < 15.0  # drift: a few degrees per minute, never frozen


def test_error_model_is_deterministic_per_rng_state():
    motion, placements = _walk()
    q = virtual_orientations(motion, placements)
    model = OrientationErrorModel.realistic()
    a = model.apply(q, motion.fps, np.random.default_rng(3))
    b = model.apply(q, motion.fps, np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
