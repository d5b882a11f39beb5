"""IMU-camera lag check: known injected lags recovered from signals and from a rendered jump."""
from __future__ import annotations

import numpy as np
import pytest

from gateway.camera import (
    CameraImperfections, PlayerPath, PlayerTracker, SyntheticCourtCamera, camera_event_signal, estimate_lag,
    imu_event_signal, jump_lag, jump_lift_m, upward_image_displacement_px,
)
from gateway.camera.paths import GRAVITY_MPS2


@pytest.mark.parametrize("lag_s", [-0.123, 0.0, 0.0417, 0.2])
def test_sub_sample_lag_between_two_sampled_signals(lag_s):
    rng = np.random.default_rng(1)
    events = rng.uniform(0.5, 9.5, 6)

    def signal(t):
        return sum(np.exp(-0.5 * ((t - e) / 0.05) ** 2) for e in events)

    t_ref = np.arange(0, 10, 0.01)
    t_other = np.arange(0, 10, 1 / 30) + 0.004
    other = 3.0 * signal(t_other - lag_s) + 0.7 + rng.normal(0, 0.02, len(t_other))
    est = estimate_lag(t_ref, signal(t_ref), t_other, other, max_lag_s=0.3)
    assert est.lag_s == pytest.approx(lag_s, abs=0.003)  # well below both sample periods (10 ms, 33 ms)
    assert est.correlation > 0.95


def test_unrelated_signals_have_low_confidence():
    rng = np.random.default_rng(2)
    t = np.arange(0, 10, 0.01)
    est = estimate_lag(t, rng.normal(size=len(t)), t, rng.normal(size=len(t)), max_lag_s=0.3)
    assert est.correlation < 0.2


def test_jump_seen_by_imu_and_rendered_camera_gives_the_injected_latency(court_camera, calibration):
    latency_s = 0.08
    t = np.arange(0.0, 4.0, 0.002)
    lift = jump_lift_m(t, ((1.0, 0.35), (2.6, 0.25)))
    path = PlayerPath(t, np.tile([1.0, -8.0], (len(t), 1)), np.zeros(len(t)), lift)
    source = SyntheticCourtCamera(path, camera=court_camera, seed=3,
                                  imperfections=CameraImperfections(latency_s=latency_s, jitter_s=0.002))
    tracker = PlayerTracker(calibration)
    records = [r for r in (tracker.update(f) for f in source) if r is not None]
    t_cam = np.array([r.t_host_s for r in records])
    centroids = np.array([r.centroid_px for r in records])
    cam = camera_event_signal(t_cam, upward_image_displacement_px(calibration, centroids))
    # trunk accelerometer at 100 Hz on the true clock: gravity + vertical acceleration, noise
    t_imu = np.arange(0.0, 4.0, 0.01)
    vertical_g = np.interp(t_imu, t, path.vertical_acceleration_mps2()) / GRAVITY_MPS2
    acc = np.column_stack([np.zeros_like(t_imu), 1 + vertical_g, np.zeros_like(t_imu)])
    acc += np.random.default_rng(0).normal(0, 0.02, acc.shape)
    est = estimate_lag(t_imu, imu_event_signal(t_imu, acc), t_cam, cam, max_lag_s=0.3)
    assert jump_lag(t_imu, acc, t_cam, centroids, calibration, max_lag_s=0.3) == est  # the one-call helper
    print(f"jump lag estimate {est.lag_s * 1000:.1f} ms (true {latency_s * 1000:.0f} ms), r={est.correlation:.2f}")
    assert est.lag_s == pytest.approx(latency_s, abs=0.010)  # under a third of a 33 ms frame
    assert est.correlation > 0.7
