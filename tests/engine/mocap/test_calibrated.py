"""Calibrated placements and the engine-side reader of sensor-calibration records (no gateway import)."""
import json

import numpy as np
import pytest

from engine.mocap import (MalformedFileError, SensorPlacement, calibrated_placements, load_sensor_calibration,
                          placements_from_calibration, virtual_accelerometers)
from engine.mocap import quaternions as quat
from tests.engine.mocap.helpers import axis_angle, chain_skeleton, constant_motion


def _placements():
    return [SensorPlacement("left_forearm", 1, np.array([0.1, 0, 0]), np.eye(3)),
            SensorPlacement("right_forearm", 2, np.zeros(3), np.eye(3))]


def _record(path, sensors, schema="courtside.sensor_calibration", version=1, orientation=None):
    """A record of ``sensors`` (id -> (segment, rotation, correction, passed)); ``orientation``: id -> the
    optional per-sensor fields to add."""
    doc = {"schema": schema, "schema_version": version, "sensors": {
        sid: {"segment": seg, "rotation": np.asarray(rot).tolist(), "gravity_sensor_g": [0.0, 1.02, 0.0],
              "norm_error_g": 0.02, "correction_deg": corr, "passed": passed, **(orientation or {}).get(sid, {})}
        for sid, (seg, rot, corr, passed) in sensors.items()}}
    path.write_text(json.dumps(doc))
    return path


def test_calibrated_placements_replace_rotation_and_bias_of_named_sensors_only():
    turn = quat.to_matrix(axis_angle("X", 0.4))
    out = calibrated_placements(_placements(), {"left_forearm": turn}, bias_g={"left_forearm": [0.0, 0.1, 0.0]})
    np.testing.assert_allclose(out[0].rotation, turn)
    assert np.array_equal(out[1].rotation, np.eye(3)) and out[1].bias_g is None
    motion = constant_motion(chain_skeleton(), 4, 100.0)
    acc = virtual_accelerometers(motion, out)
    np.testing.assert_allclose(acc[:, 0], np.tile(turn.T @ [0, 1, 0] + [0, 0.1, 0], (4, 1)), atol=1e-12)
    np.testing.assert_allclose(acc[:, 1], np.tile([0, 1, 0], (4, 1)), atol=1e-12)
    with pytest.raises(ValueError, match="unknown sensor placement"):
        calibrated_placements(_placements(), {"elbow": np.eye(3)})
    with pytest.raises(ValueError, match="proper 3x3 rotation"):
        calibrated_placements(_placements(), {"left_forearm": np.diag([1.0, 1.0, -1.0])})


def test_record_reader_and_frame_check(tmp_path):
    turn = quat.to_matrix(axis_angle("Z", np.radians(20)))
    path = _record(tmp_path / "r.json", {"st0/1": ("left_forearm", turn, 20.0, True), "st0/2": ("chest", np.eye(3), 0.0, False)})
    cal = load_sensor_calibration(path)
    assert cal.sensor_ids == {"left_forearm": "st0/1", "chest": "st0/2"} and cal.failed == ["chest"]
    np.testing.assert_allclose(cal.bias_along_gravity_g["left_forearm"], [0.0, 0.02, 0.0])
    out = placements_from_calibration(_placements(), cal, with_bias=True)  # "chest" is not worn here: ignored
    np.testing.assert_allclose(out[0].rotation, turn)
    np.testing.assert_allclose(out[0].bias_g, [0.0, 0.02, 0.0])
    assert out[1].bias_g is None
    # the record says 20 deg of correction, but against these frames the rotation is 160 deg away
    flipped = _record(tmp_path / "f.json", {"st0/1": ("left_forearm", np.diag([-1.0, -1.0, 1.0]) @ turn, 20.0, True)})
    with pytest.raises(ValueError, match="another skeleton's joint frames"):
        placements_from_calibration(_placements(), load_sensor_calibration(flipped))


@pytest.mark.parametrize("write, problem", [
    (lambda p: p.write_text("{not json"), "not JSON"),
    (lambda p: _record(p, {"s": ("left_forearm", np.eye(3), 0.0, True)}, schema="courtside.court_calibration"), "schema"),
    (lambda p: _record(p, {"s": ("left_forearm", np.eye(3), 0.0, True)}, version=2), "schema_version"),
    (lambda p: _record(p, {"s": ("left_forearm", np.eye(3) * 2, 0.0, True)}), "not a proper 3x3 rotation"),
    (lambda p: _record(p, {"s": ("left_forearm", np.eye(3), 0.0, True), "t": ("left_forearm", np.eye(3), 0.0, True)}), "two sensors"),
    (lambda p: p.write_text(json.dumps({"schema": "courtside.sensor_calibration", "schema_version": 1,
                                        "sensors": {"s": {"segment": "left_forearm"}}})), "bad entry"),
    (lambda p: _record(p, {"s": ("left_forearm", np.eye(3), 0.0, True)}, orientation={"s": {"orientation_yaw_rad": 0.3}}),
     "go together"),
    (lambda p: _record(p, {"s": ("left_forearm", np.eye(3), 0.0, True)},
                       orientation={"s": {"orientation_yaw_rad": 0.3, "orientation_mount_wxyz": [2.0, 0, 0, 0]}}),
     "not a unit quaternion"),
])
def test_bad_records_name_the_file_and_problem(tmp_path, write, problem):
    path = tmp_path / "bad.calibration.json"
    write(path)
    with pytest.raises(MalformedFileError, match=problem) as info:
        load_sensor_calibration(path)
    assert "bad.calibration.json" in str(info.value)


YAWS = {"st0/1": 0.7, "st0/2": -2.9}
MOUNTS = {"st0/1": quat.from_rotvec(np.array([0.05, 0.0, -0.03])), "st0/2": -quat.from_rotvec(np.array([0, 0.1, 0]))}


def _oriented(ids) -> dict:
    return {sid: {"orientation_yaw_rad": YAWS[sid], "orientation_mount_wxyz": MOUNTS[sid].tolist()} for sid in ids}


def test_orientation_calibration_of_the_worn_sensors_in_their_order(tmp_path):
    """The optional per-sensor pair becomes the engine's OrientationCalibration, ordered like the sensors asked
    for; a strapping stored with either sign is the same rotation."""
    sensors = {"st0/1": ("left_forearm", np.eye(3), 0.0, True), "st0/2": ("right_forearm", np.eye(3), 0.0, True)}
    cal = load_sensor_calibration(_record(tmp_path / "r.json", sensors, orientation=_oriented(YAWS)))
    solved = cal.orientation_calibration(["right_forearm", "left_forearm"])
    np.testing.assert_array_equal(solved.yaw_rad, [YAWS["st0/2"], YAWS["st0/1"]])
    np.testing.assert_array_equal(solved.mount_wxyz, [MOUNTS["st0/2"], MOUNTS["st0/1"]])
    q = quat.normalize(np.random.default_rng(0).normal(size=(5, 2, 4)))  # the calibration maps readings alike
    np.testing.assert_allclose(solved.world(q)[:, ::-1], cal.orientation_calibration(["left_forearm", "right_forearm"]).world(q[:, ::-1]),
                               atol=1e-12)


def test_records_without_orientations_or_with_a_worn_sensor_lacking_one_pose_by_tilt(tmp_path, caplog):
    """An old (accelerometer-only) record loads as before with no orientation calibration; one where a worn
    sensor streamed no orientation gives none either (the yaw posing needs every worn segment's), and a log line
    names that sensor. A sensor that is not worn does not count."""
    sensors = {"st0/1": ("left_forearm", np.eye(3), 0.0, True), "st0/2": ("right_forearm", np.eye(3), 0.0, True)}
    caplog.set_level("INFO", logger="engine.mocap.calibrated")
    old = load_sensor_calibration(_record(tmp_path / "old.json", sensors))
    assert old.orientation == {} and old.orientation_calibration(["left_forearm", "right_forearm"]) is None
    assert "no orientation calibration in the record" in caplog.text
    caplog.clear()
    mixed = load_sensor_calibration(_record(tmp_path / "mixed.json", sensors, orientation=_oriented(["st0/1"])))
    assert mixed.orientation_calibration(["left_forearm", "right_forearm"]) is None
    assert "no orientation calibration for right_forearm " in caplog.text and "tilt only" in caplog.text
    assert mixed.orientation_calibration(["left_forearm"]).yaw_rad.tolist() == [YAWS["st0/1"]]
