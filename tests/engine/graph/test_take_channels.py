"""Orientation and angular rate read from both take layouts into `Observations`, on the same frames as the
accelerations (the synthesis-input npz that `import-imu` writes, and the gateway's export)."""
from __future__ import annotations

import numpy as np

from engine.graph.inputs import read_take
from engine.stream import resample_uniform

SENSORS = ["chest", "pelvis", "wrist_l"]


def _turning(n: int, fps: float, rate: float) -> np.ndarray:
    half = 0.5 * rate * np.arange(n) / fps
    return np.c_[np.cos(half), np.zeros(n), np.sin(half), np.zeros(n)]


def test_synthesis_file_channels_follow_the_kept_columns(tmp_path):
    """Columns the graph lacks are dropped from every channel alike; the frames are resample_uniform's."""
    rng = np.random.default_rng(1)
    n, fps = 240, 120.0
    acc = rng.normal(0, 0.1, (n, 4, 3)) + [0, 1, 0]
    quat = np.stack([_turning(n, fps, r) for r in (0.5, 1.0, 2.0, 3.0)], axis=1)
    gyro = np.broadcast_to(np.array([[0, r, 0] for r in (0.5, 1.0, 2.0, 3.0)], float), (n, 4, 3)).copy()
    quat[50, 3] = np.nan  # a sensor without a value here
    np.savez(tmp_path / "take.npz", acc_g=acc, fps=fps, quat_wxyz=quat, gyro_rps=gyro,
             sensor_names=np.array(["chest", "ankle_r", "pelvis", "wrist_l"]))
    obs = read_take(tmp_path / "take.npz", SENSORS, 30.0).obs
    keep = [0, 2, 3]
    want = resample_uniform(acc[:, keep], fps, 30.0, quat_wxyz=quat[:, keep], gyro_rps=gyro[:, keep])
    assert obs.sensor_indices == (0, 1, 2)
    assert np.array_equal(obs.quat_wxyz, want.quat_wxyz, equal_nan=True) and np.array_equal(obs.gyro_rps, want.gyro_rps)
    np.testing.assert_allclose(obs.gyro_rps[:, 1], np.tile([0, 2.0, 0], (len(obs.gyro_rps), 1)), atol=1e-12)
    assert np.isnan(obs.quat_wxyz[:, 2]).any() and not np.isnan(obs.quat_wxyz[:, :2]).any()


def test_accelerometer_only_take_has_no_channels(tmp_path):
    np.savez(tmp_path / "take.npz", acc_g=np.tile([0.0, 1.0, 0.0], (120, 3, 1)), fps=60.0)
    obs = read_take(tmp_path / "take.npz", SENSORS, 30.0).obs
    assert obs.quat_wxyz is None and obs.gyro_rps is None


def test_gateway_export_channels_on_the_live_frames(tmp_path):
    """A sensor that streamed orientation and one that did not: NaN columns for the second, the first's values
    through the live resampler (the raw streams kept for the fixed-lag path carry them too)."""
    t = 10.0 + np.arange(300) / 100.0
    arrays = {}
    for k in range(3):
        arrays[f"st1/{k}/t_host_s"] = t + 0.001 * k
        arrays[f"st1/{k}/acc_g"] = np.tile([0.0, 1.0, 0.0], (len(t), 1))
    arrays["st1/0/quat_wxyz"] = _turning(len(t), 100.0, 1.0).astype(np.float32)
    arrays["st1/0/gyro_rps"] = np.tile([0.0, 1.0, 0.0], (len(t), 1)).astype(np.float32)
    np.savez(tmp_path / "export.npz", **arrays)
    take = read_take(tmp_path / "export.npz", SENSORS, 30.0)
    obs = take.obs
    assert obs.quat_wxyz.shape == (len(obs.acc_g), 3, 4) and len(obs.acc_g) > 60
    assert not np.isnan(obs.quat_wxyz[:, 0]).any() and np.isnan(obs.quat_wxyz[:, 1:]).all()
    np.testing.assert_allclose(obs.gyro_rps[:, 0, 1], 1.0, atol=1e-6)
    angle = take.t_s - 10.0  # a rotation about Y by 1 rad/s since t = 10 s
    want = np.c_[np.cos(angle / 2), np.zeros_like(angle), np.sin(angle / 2), np.zeros_like(angle)]
    dots = np.abs(np.einsum("fi,fi->f", obs.quat_wxyz[:, 0], want))
    assert np.degrees(2 * np.arccos(np.minimum(dots, 1.0))).max() < 0.01
    assert len(take.streams.samples["st1/0"]) == 4 and len(take.streams.samples["st1/1"]) == 2
