"""Building blocks with exact answers: rotations from gravity, yaw ambiguity, offset fit, tap timing."""
from __future__ import annotations

import numpy as np
import pytest

from gateway.calibration import (
    detect_tap, fit_offset_g, minimal_rotation, rotation_angle_deg, rotation_from_directions,
    sensor_to_segment_rotation, stillness,
)
from gateway.calibration.alignment import UP


def random_rotation(rng) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_minimal_rotation_maps_directions_including_opposite():
    rng = np.random.default_rng(0)
    for a, b in [(rng.normal(size=3), rng.normal(size=3)), (UP, -UP), (UP, UP)]:
        r = minimal_rotation(a, b)
        np.testing.assert_allclose(r @ (a / np.linalg.norm(a)), b / np.linalg.norm(b), atol=1e-12)
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)


def test_yaw_about_up_is_not_observable_from_one_pose_but_is_from_two():
    rng = np.random.default_rng(1)
    nominal = random_rotation(rng)
    yaw = minimal_rotation([1.0, 0, 0], [np.cos(0.3), 0, np.sin(0.3)])  # 17 deg about up
    true = yaw @ nominal
    reading = true.T @ UP
    one_pose = sensor_to_segment_rotation(reading, nominal)
    np.testing.assert_allclose(one_pose @ reading, UP, atol=1e-12)  # gravity fits perfectly...
    assert rotation_angle_deg(one_pose @ true.T) == pytest.approx(np.degrees(0.3), abs=1e-6)  # ...yaw is lost
    lean_up = np.array([0.0, np.cos(0.6), np.sin(0.6)])  # second pose: segment leant forward
    two_pose = rotation_from_directions(np.stack([true.T @ UP, true.T @ lean_up]), np.stack([UP, lean_up]))
    assert rotation_angle_deg(two_pose @ true.T) < 1e-4
    with pytest.raises(ValueError, match="non-parallel"):
        rotation_from_directions(np.stack([UP, UP]), np.stack([UP, UP]))


def test_offset_fit_from_six_tumble_orientations():
    rng = np.random.default_rng(2)
    bias = np.array([0.03, -0.05, 0.02])
    faces = np.vstack([np.eye(3), -np.eye(3)])
    tilts = [minimal_rotation(f, f + rng.normal(0, 0.1, 3)) @ f for f in faces]
    means = np.array(tilts) + bias + rng.normal(0, 0.001, (6, 3))
    np.testing.assert_allclose(fit_offset_g(means), bias, atol=0.003)
    with pytest.raises(ValueError, match="orientations"):
        fit_offset_g(means[:2])


@pytest.mark.parametrize("frac", [0.0, 0.3, 0.5, 0.81])
def test_tap_time_within_one_sample(frac):
    rate = 100.0
    rng = np.random.default_rng(3)
    t = 50.0 + np.arange(300) / rate + rng.normal(0, 0.0005, 300)  # host-clock jitter
    t.sort()
    t_true = 50.0 + (137 + frac) / rate
    acc = np.tile([0.0, 1.0, 0.0], (300, 1)) + rng.normal(0, 0.01, (300, 3))
    phase = (t - t_true) / 0.03 + 0.5
    acc[:, 0] += 3.0 * np.where((phase > 0) & (phase < 1), np.sin(np.pi * np.clip(phase, 0, 1)), 0.0)
    event = detect_tap(t, acc)
    assert event is not None and abs(event.t_s - t_true) <= 1.0 / rate
    assert event.peak_g > 1.5
    assert detect_tap(t[:140], acc[:140]) is None  # the spike is not complete yet
    assert detect_tap(t[:120], acc[:120]) is None  # no spike at all


def test_stillness_statistics_see_rotation_in_place():
    t = np.arange(100) / 100.0
    angle = 0.5 * t
    turning = np.column_stack([np.sin(angle), np.cos(angle), np.zeros_like(t)])  # |a| = 1 g throughout
    st = stillness(t, turning)
    assert st.norm_std_g < 1e-12 and st.axis_std_g > 0.05
    assert st.meter(0.02) == 0.0 and stillness(t, np.tile(UP, (100, 1))).meter(0.02) == 1.0
