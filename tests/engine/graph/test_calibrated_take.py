"""`synthesize --calibration` on a gateway take: the raw recorded samples the fixed-lag live path resamples are
rotated into the nominal frames exactly as the observations are (a rotation commutes with the box filter)."""
from __future__ import annotations

import json

import numpy as np

from engine.graph.calibrated_input import calibrated_take
from engine.graph.inputs import read_take
from engine.mocap import load_clip, sample_clips, standard_placements

SENSORS = ["left_forearm", "right_forearm"]


def test_calibrated_take_rotates_raw_samples_and_observations_alike(tmp_path):
    skeleton = load_clip(sample_clips()["16_01"]).skeleton
    nominal = {p.name: p.rotation for p in standard_placements(skeleton, tuple(SENSORS))}
    a = np.radians(30.0)
    twist = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    record = tmp_path / "take.calibration.json"
    record.write_text(json.dumps({"schema": "courtside.sensor_calibration", "schema_version": 1, "sensors": {
        "st1/0": {"segment": "left_forearm", "rotation": (nominal["left_forearm"] @ twist).tolist(),
                  "gravity_sensor_g": [0, 1, 0], "norm_error_g": 0.0, "correction_deg": 30.0, "passed": True}}}))
    t = 10.0 + np.arange(400) / 100.0
    arrays = {}
    for k in range(2):
        arrays[f"st1/{k}/t_host_s"] = t + 0.001 * k
        arrays[f"st1/{k}/acc_g"] = np.c_[np.sin(3 * t + k), np.cos(2 * t), np.full(len(t), 1.0)]
    np.savez(tmp_path / "export.npz", **arrays)
    take = read_take(tmp_path / "export.npz", SENSORS, 30.0)
    out = calibrated_take(take, skeleton, SENSORS, record)
    correction = twist  # C = R_nominal^T R_measured
    np.testing.assert_allclose(out.streams.samples["st1/0"][1], arrays["st1/0/acc_g"] @ correction.T, atol=1e-12)
    assert np.array_equal(out.streams.samples["st1/1"][1], arrays["st1/1/acc_g"])  # not calibrated: untouched
    np.testing.assert_allclose(out.obs.acc_g[:, 0], take.obs.acc_g[:, 0] @ correction.T, atol=1e-12)
    assert np.array_equal(out.obs.acc_g[:, 1], take.obs.acc_g[:, 1])
    assert np.array_equal(take.streams.samples["st1/0"][1], arrays["st1/0/acc_g"])  # the input take is not changed
