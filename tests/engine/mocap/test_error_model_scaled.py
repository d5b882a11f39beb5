"""The signal-scaled sensor error model and its `measured_real` preset (docs/engine-mocap.md)."""
from __future__ import annotations

import numpy as np
import pytest

from engine.mocap import SensorErrorModel
from engine.mocap.bench import _calibration_readings, _gap
from engine.mocap.sensors import REAL_GAP_G2


def test_noise_scales_with_the_dynamic_part_of_the_reading():
    t = np.arange(20000) / 30.0
    acc = np.zeros((len(t), 2, 3))
    acc[:, :, 1] = 1.0  # gravity
    acc[:, 0, 0] = 2.0 * np.sin(2 * np.pi * 1.3 * t)  # sensor 0 moves; sensor 1 rests
    model = SensorErrorModel(noise_rel=0.3, saturation_g=None)
    out = model.apply(acc, 30.0, np.random.default_rng(0))
    np.testing.assert_array_equal(out[:, 1], acc[:, 1])  # at rest (no dynamic part): no noise at all
    dyn = np.linalg.norm(acc[:, 0] - acc[:, 0].mean(axis=0), axis=-1)
    moving = dyn > 0.5
    z = (out[moving, 0] - acc[moving, 0]) / dyn[moving, None]
    assert z.std() == pytest.approx(0.3, rel=0.03)  # sd = noise_rel x |dyn|, per axis


def test_sensor_scale_weights_each_sensor():
    acc = np.random.default_rng(1).normal(0, 1, (5000, 2, 3))
    out = SensorErrorModel(noise_g=0.2, sensor_scale=(0.0, 2.0), saturation_g=None).apply(
        acc, 30.0, np.random.default_rng(2))
    np.testing.assert_array_equal(out[:, 0], acc[:, 0])
    assert (out[:, 1] - acc[:, 1]).std() == pytest.approx(0.4, rel=0.05)
    with pytest.raises(ValueError, match="sensor_scale"):
        SensorErrorModel(noise_g=0.2, sensor_scale=(1.0,)).apply(acc, 30.0, np.random.default_rng(2))


def test_presets_have_the_measured_gaps():
    clean = _calibration_readings()
    assert _gap(SensorErrorModel.measured_real(), clean, 0) == pytest.approx(REAL_GAP_G2, rel=0.1)
    assert _gap(SensorErrorModel.seed000(), clean, 0) == pytest.approx(1.6, rel=0.1)
