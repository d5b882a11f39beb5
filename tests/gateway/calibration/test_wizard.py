"""The calibration wizard driven like the console would, on an emulated subject with known mounting."""
from __future__ import annotations

import json

import numpy as np
import pytest

from engine.mocap import SEED000_SENSORS, load_sensor_calibration, quaternions
from engine.mocap.orientation_calibration import mean_orientation
from gateway.calibration import CalibrationRecord, CalibrationRecordError, rotation_angle_deg

from .conftest import RATE_HZ, feed, tilt_rotation, with_orientation


def spike(t_peak: float, height_g: float = 4.0, width_s: float = 0.03):
    """Override adding a half-sine impact along the sensor's x axis peaking at ``t_peak``."""
    def apply(t, acc):
        phase = (t - t_peak) / width_s + 0.5
        bump = np.where((phase > 0) & (phase < 1), np.sin(np.pi * np.clip(phase, 0, 1)), 0.0)
        return acc + np.outer(height_g * bump, [1.0, 0.0, 0.0])
    return apply


def run_to_npose(wizard, subject, rng) -> float:
    assert wizard.confirm() and wizard.step == "placement"
    t = feed(wizard, subject, 0.0, 0.5, rng)
    assert wizard.confirm(), wizard.snapshot()["messages"]
    assert wizard.step == "npose"
    return t


def test_still_subject_completes_and_recovers_rotations_and_bias(wizard, subject, tmp_path):
    rng = np.random.default_rng(0)
    t = run_to_npose(wizard, subject, rng)
    snaps = []
    while wizard.step == "npose" and t < 10:
        t = feed(wizard, subject, t, t + 0.25, rng)
        snaps.append(wizard.snapshot())
    assert wizard.step == "tap"
    assert any(s["phase"] == "capturing" and 0 < s["countdown_s"] < 2.0 for s in snaps)
    assert all(v["stillness"] == 1.0 for v in snaps[-1]["sensors"].values())
    assert t < 0.5 + 1.0 + 2.0 + 0.6  # auto-start after 1 s of stillness, 2 s capture
    for sid, result in wizard.results.items():
        error = rotation_angle_deg(result.rotation @ subject.true_rotation[sid].T)
        assert error < 2.0, (sid, error)
        assert result.correction_deg > 5.0  # the mounting error really was corrected
        reading = subject.gravity_reading(sid) + subject.bias_g[sid]
        assert result.norm_error_g == pytest.approx(np.linalg.norm(reading) - 1.0, abs=0.002)
        assert result.passed
    # sync tap on one sensor, between samples
    tapped, t_tap = "st0/4", t + 1.234
    t = feed(wizard, subject, t, t + 2.0, rng, {tapped: spike(t_tap)})
    assert wizard.step == "review"
    assert wizard.tap["sensor_id"] == tapped
    assert abs(wizard.tap["t_s"] - t_tap) <= 1.0 / RATE_HZ
    q = wizard.snapshot()["quality"]
    assert q["passed"] and q["grade"] in ("good", "fair") and 0 < q["score"] <= 100
    assert wizard.confirm() and wizard.step == "done"
    json.dumps(wizard.snapshot())  # console-ready
    path = tmp_path / "take01.calibration.json"
    npz = wizard.record(subject="p1", take="take01").save(path)
    loaded = CalibrationRecord.load(path)
    assert npz.is_file() and loaded.subject == "p1" and loaded.passed
    for sid in subject.segments:
        np.testing.assert_allclose(loaded.rotation(sid), wizard.results[sid].rotation)
        t_raw, acc_raw = loaded.raw["npose"][sid]
        assert len(t_raw) == pytest.approx(2.0 * RATE_HZ, abs=2) and acc_raw.shape == (len(t_raw), 3)
    assert set(loaded.raw["tap"]) == set(subject.segments)


def _quat_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(2 * np.arccos(np.clip(abs(np.dot(a, b)), 0.0, 1.0))))


def test_orientation_sensors_get_their_yaw_offsets_and_strapping(wizard, subject, tmp_path):
    """Sensors that stream orientations through the emulators' realistic filter error model: the still N-pose
    also gives each sensor's earth-frame yaw -- relative to the pelvis sensor, the emulated offsets at the capture
    within 1.5 deg (drift, random walk and tilt noise are what is left) -- and its strapping, the subject's true
    mounting within the filter's tilt error during the capture (+ 0.5 deg: one still pose cannot tell the two
    apart); the record carries both, and the engine reads them back as an OrientationCalibration."""
    subject = with_orientation(subject, seed=7)
    rng = np.random.default_rng(1)
    t = run_to_npose(wizard, subject, rng)
    while wizard.step == "npose" and t < 10:
        t = feed(wizard, subject, t, t + 0.25, rng)
    assert wizard.step == "tap"
    assert "orientation calibrated for 6 of 6 sensors" in wizard.snapshot()["messages"][-1]
    t_samples = wizard._raw["npose"]["st0/0"][0]
    t_capture = float(np.mean(t_samples))
    known, tilt = subject.yaw_offsets_rad(t_capture), subject.filter_tilt_deg(t_samples)
    pelvis = next(sid for sid, seg in subject.segments.items() if seg == "lower_back")
    solved = {sid: r.orientation_yaw_rad for sid, r in wizard.results.items()}
    errors = {}
    for sid, seg in subject.segments.items():
        relative = (solved[sid] - solved[pelvis]) - (known[sid] - known[pelvis])
        errors[seg] = float(np.degrees(np.angle(np.exp(1j * relative))))
        nominal = wizard.segments[seg].nominal_rotation
        strap = quaternions.from_matrix(nominal.T @ subject.true_rotation[sid])  # sensor axes -> nominal frame
        assert _quat_angle_deg(wizard.results[sid].orientation_mount_wxyz, strap) < tilt[sid] + 0.5, (seg, tilt)
    print("yaw relative to the pelvis, solved - emulated (deg):", {k: round(v, 2) for k, v in errors.items()})
    assert max(abs(e) for e in errors.values()) < 1.5, errors
    assert {s["segment"]: s["orientation_yaw_deg"] is not None for s in wizard.snapshot()["sensors"].values()} \
        == dict.fromkeys(subject.segments.values(), True)
    wizard.confirm()  # skip the tap
    assert wizard.confirm() and wizard.step == "done"
    path = tmp_path / "oriented.calibration.json"
    wizard.record().save(path)
    loaded = CalibrationRecord.load(path)
    for sid, result in wizard.results.items():
        again = loaded.sensors[sid]
        assert again.orientation_yaw_rad == result.orientation_yaw_rad
        mount = result.orientation_mount_wxyz
        np.testing.assert_array_equal(again.orientation_mount_wxyz, mount if mount[0] >= 0 else -mount)
        t_raw, acc_raw, quat_raw = loaded.raw["npose"][sid]
        assert quat_raw.shape == (len(t_raw), 4) and np.isfinite(quat_raw).all()
    by_segment = {seg: sid for sid, seg in subject.segments.items()}
    engine_side = load_sensor_calibration(path).orientation_calibration(SEED000_SENSORS)
    assert engine_side.yaw_rad.tolist() == [solved[by_segment[n]] for n in SEED000_SENSORS]
    # what the engine gets out of it: over the capture, each segment's nominal sensor orientation in the pose
    # (facing +Z, as the subject did), from the readings
    world = engine_side.world(np.stack([subject.quats(by_segment[n], t_samples) for n in SEED000_SENSORS], axis=1))
    for k, name in enumerate(SEED000_SENSORS):
        off = _quat_angle_deg(mean_orientation(world)[k], wizard.segments[name].pose_orientation_wxyz)
        assert off < 1.0, (name, off)


def test_an_accelerometer_only_sensor_among_orientation_ones_keeps_the_old_record(wizard, subject, tmp_path):
    """One sensor streams no orientation (NaN rows, as the gateway forwards an acc-only sensor on a v2
    station): it is calibrated as before, without the orientation fields, the others get theirs; the engine then
    poses by tilt only (it needs every worn segment's yaw)."""
    subject = with_orientation(subject, seed=8)
    subject.quat_device[:, 2] = np.nan
    rng = np.random.default_rng(2)
    t = run_to_npose(wizard, subject, rng)
    while wizard.step == "npose" and t < 10:
        t = feed(wizard, subject, t, t + 0.25, rng)
    assert wizard.step == "tap" and wizard.results["st0/2"].passed
    assert wizard.results["st0/2"].orientation_yaw_rad is None
    assert all(r.orientation_yaw_rad is not None for sid, r in wizard.results.items() if sid != "st0/2")
    path = tmp_path / "mixed.calibration.json"
    wizard.record().save(path)
    doc = json.loads(path.read_text())
    assert "orientation_yaw_rad" not in doc["sensors"]["st0/2"] and "orientation_mount_wxyz" in doc["sensors"]["st0/1"]
    assert len(CalibrationRecord.load(path).raw["npose"]["st0/2"]) == 2  # times and accelerations only
    assert load_sensor_calibration(path).orientation_calibration(SEED000_SENSORS) is None


def test_biased_sensor_fails_with_reason(wizard, subject):
    rng = np.random.default_rng(1)
    bad = "st0/2"
    up_in_sensor = subject.gravity_reading(bad)
    subject.bias_g[bad] = 0.08 * up_in_sensor  # 0.08 g along gravity: |a| reads 1.08 g
    t = run_to_npose(wizard, subject, rng)
    feed(wizard, subject, t, t + 4.0, rng)
    result = wizard.results[bad]
    assert result.norm_error_g == pytest.approx(0.08, abs=0.003)
    assert not result.passed and "bias or scale" in result.reasons[0]
    assert all(r.passed for sid, r in wizard.results.items() if sid != bad)
    assert wizard.quality()["passed"] is False


def test_moving_subject_is_rejected_with_a_reason_then_captured(wizard, subject):
    rng = np.random.default_rng(2)
    t = run_to_npose(wizard, subject, rng)
    mover = "st0/0"

    def swing(t_arr, acc):  # arm swings 1.5 s into the capture
        moving = t_arr > t + 2.0
        return acc + np.outer(np.where(moving, 0.3 * np.sin(2 * np.pi * 1.5 * t_arr), 0.0), [0.0, 0.0, 1.0])

    t = feed(wizard, subject, t, t + 3.0, rng, {mover: swing})
    snap = wizard.snapshot()
    assert snap["step"] == "npose" and snap["phase"] == "waiting_for_stillness" and wizard.rejections == 1
    assert any(f"sensor {mover}" in m and "moved" in m for m in snap["messages"])
    assert snap["sensors"][mover]["stillness"] < 0.5
    t = feed(wizard, subject, t, t + 2.0, rng, {mover: swing})  # still moving: never starts
    assert wizard.step == "npose" and wizard.rejections == 1
    feed(wizard, subject, t, t + 4.0, rng)  # stands still again
    assert wizard.step == "tap" and len(wizard.results) == len(subject.segments)


def test_redo_of_one_step_keeps_the_others(wizard, subject):
    rng = np.random.default_rng(3)
    t = run_to_npose(wizard, subject, rng)
    t = feed(wizard, subject, t, t + 4.0, rng)
    t = feed(wizard, subject, t, t + 1.0, rng, {"st0/1": spike(t + 0.5)})
    assert wizard.step == "review"
    first_results = dict(wizard.results)
    assert wizard.tap["sensor_id"] == "st0/1"  # the first tap, which the redo replaces
    wizard.redo("tap")
    assert wizard.step == "tap" and wizard.tap is None and wizard.results == first_results
    t = feed(wizard, subject, t, t + 1.0, rng, {"st0/3": spike(t + 0.4)})
    assert wizard.step == "review" and wizard.tap["sensor_id"] == "st0/3" and wizard.results == first_results
    # the strap on st0/5 slipped: re-mount, redo only the N-pose
    up = wizard.segments["chest"].expected_up
    subject.true_rotation["st0/5"] = tilt_rotation(rng, up, 15.0) @ subject.true_rotation["st0/5"]
    wizard.redo("npose")
    assert wizard.step == "npose" and wizard.results == {} and wizard.tap is not None
    feed(wizard, subject, t, t + 4.0, rng)
    assert wizard.step == "review" and wizard.tap["sensor_id"] == "st0/3"
    assert rotation_angle_deg(wizard.results["st0/5"].rotation @ subject.true_rotation["st0/5"].T) < 2.0


def test_placement_check_refuses_an_upside_down_sensor(wizard, subject):
    rng = np.random.default_rng(4)
    flip = np.diag([-1.0, -1.0, 1.0])  # 180 deg about the sensor's z: its x (up on the lower back) points down
    subject.true_rotation["st0/4"] = subject.true_rotation["st0/4"] @ flip
    assert wizard.confirm()
    feed(wizard, subject, 0.0, 0.5, rng)
    assert not wizard.confirm() and wizard.step == "placement"
    snap = wizard.snapshot()
    assert snap["sensors"]["st0/4"]["placement_ok"] is False
    assert "upside down" in snap["messages"][-1] and "st0/4" in snap["messages"][-1]
    subject.true_rotation["st0/4"] = subject.true_rotation["st0/4"] @ flip  # fixed
    feed(wizard, subject, 0.5, 1.0, rng)
    assert wizard.confirm() and wizard.step == "npose"


def test_operator_errors(specs):
    from gateway.calibration import CalibrationWizard

    wiz = CalibrationWizard(specs)
    assert not wiz.confirm() and "assign at least one" in wiz.snapshot()["messages"][-1]
    with pytest.raises(ValueError, match="unknown segment 'tail'"):
        wiz.assign("x", "tail")
    with pytest.raises(ValueError, match="cannot redo 'done'"):
        wiz.redo("done")
    with pytest.raises(RuntimeError, match="no N-pose"):
        wiz.record()
    wiz.assign("a", "chest")
    wiz.assign("b", "chest")  # replaces a
    assert wiz.assignment == {"b": "chest"}


def test_record_load_errors_name_the_file(tmp_path, wizard, subject):
    rng = np.random.default_rng(5)
    t = run_to_npose(wizard, subject, rng)
    feed(wizard, subject, t, t + 4.0, rng)
    path = tmp_path / "cal.json"
    wizard.record().save(path)
    doc = json.loads(path.read_text())
    doc["schema_version"] = 99
    bad = tmp_path / "future.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(CalibrationRecordError, match="future.json: unsupported schema_version 99"):
        CalibrationRecord.load(bad)
    doc["schema_version"] = 1
    doc["sensors"]["st0/0"]["rotation"] = [[2, 0, 0], [0, 1, 0], [0, 0, 1]]
    bad.write_text(json.dumps(doc))
    with pytest.raises(CalibrationRecordError, match="'st0/0': rotation is not a proper"):
        CalibrationRecord.load(bad)
    (tmp_path / "cal.npz").write_bytes(b"garbage")
    with pytest.raises(CalibrationRecordError, match="cal.npz: raw samples unreadable"):
        CalibrationRecord.load(path)
    assert CalibrationRecord.load(path, with_raw=False).raw == {}



def test_reassigning_a_sensor_invalidates_only_the_npose(wizard, subject):
    rng = np.random.default_rng(6)
    t = run_to_npose(wizard, subject, rng)
    t = feed(wizard, subject, t, t + 4.0, rng)
    t = feed(wizard, subject, t, t + 1.0, rng, {"st0/1": spike(t + 0.5)})
    assert wizard.step == "review"
    wizard.redo("assign")
    wizard.assign("st0/0", "left_forearm")  # unchanged: nothing lost
    assert len(wizard.results) == 6 and "npose" in wizard.snapshot()["completed"]
    wizard.unassign("st0/5")  # the chest sensor is removed
    assert "st0/5" not in wizard.results and "npose" not in wizard.snapshot()["completed"]
    assert wizard.confirm() and wizard.step == "npose"  # placement kept, tap kept, N-pose redone
    feed(wizard, subject, t, t + 4.0, rng)
    assert wizard.step == "review" and set(wizard.results) == set(subject.segments) - {"st0/5"}
    assert wizard.tap["sensor_id"] == "st0/1"


def test_moving_a_sensor_reopens_placement_and_npose(wizard, subject):
    rng = np.random.default_rng(7)
    t = run_to_npose(wizard, subject, rng)
    feed(wizard, subject, t, t + 4.0, rng)
    wizard.redo("assign")
    wizard.assign("st0/4", "chest")  # lower-back sensor moved to the chest (replacing st0/5)
    completed = set(wizard.snapshot()["completed"])
    assert "placement" not in completed and "npose" not in completed
    assert "st0/5" not in wizard.assignment and wizard.assignment["st0/4"] == "chest"
    assert wizard.confirm() and wizard.step == "placement"
