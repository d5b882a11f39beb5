"""Calibration from an ordinary recording (gateway.calibration.recording): known mountings recovered from
virtual sensors on a standing-then-walking take, with noise; the record is the wizard's."""
from __future__ import annotations

import re

import numpy as np
import pytest

from engine.errors import CourtsideError, MalformedFileError
from engine.mocap import SEED000_SENSORS, load_sensor_calibration, reading_corrections, standard_placements, \
    virtual_accelerometers
from gateway.calibration import CalibrationRecord, rotation_angle_deg
from gateway.calibration.recording import calibrate_recording, standard_segment_poses
from bench.support.imu_formats import mounted, standing_then_walking

NAMES = list(SEED000_SENSORS)
FPS = 100.0


def _take(tpose_s: float = 0.0, flip: tuple[str, ...] = (), seed: int = 3, bow_s: float = 0.0, sit_s: float = 0.0):
    motion = standing_then_walking(tpose_s=tpose_s, fps=FPS, seed=seed, bow_s=bow_s, sit_s=sit_s)
    truth = mounted(standard_placements(motion.skeleton, NAMES), seed=seed, flip=flip)
    rng = np.random.default_rng(seed)
    acc = virtual_accelerometers(motion, truth) + rng.normal(0.0, 0.01, (motion.n_frames, len(NAMES), 3))
    return acc, truth, motion


def _errors(record, truth) -> dict[str, float]:
    return {p.name: rotation_angle_deg(record.sensors[p.name].rotation @ p.rotation.T) for p in truth}


@pytest.fixture(scope="module")
def walking():
    acc, truth, motion = _take()
    return calibrate_recording(acc, FPS, NAMES, NAMES, standard_segment_poses(NAMES)), truth, acc


def test_standing_then_walking_recovers_mountings(walking):
    record, truth, _ = walking
    err = _errors(record, truth)
    nominal = {p.name: p.rotation for p in standard_placements(standing_then_walking().skeleton, NAMES)}
    off = {p.name: rotation_angle_deg(p.rotation @ nominal[p.name].T) for p in truth}
    assert min(off.values()) > 19.0  # every sensor really is strapped 20-30° off, heading included
    # gravity + the walking axis (filtered around the cadence) on pelvis and shins: measured 1.8-3.4° over six CMU
    # takes (bench/bench_calibrate.py); forearms and chest keep the nominal heading and say so
    for name in ("lower_back", "left_shin", "right_shin"):
        assert err[name] < 4.0, err
        assert not record.sensors[name].reasons
    assert any("an arm needs a second pose" in r for r in record.sensors["left_forearm"].reasons)
    assert any("the trunk needs a second pose" in r for r in record.sensors["chest"].reasons)
    assert all(s.passed and 0.1 < s.quality <= 1.0 for s in record.sensors.values())
    assert record.sensors["left_shin"].quality > 0.8


def test_second_poses_fix_the_arms_and_the_trunk():
    acc, truth, motion = _take(tpose_s=2.0, bow_s=2.0)
    end = motion.n_frames / FPS
    windows = {"tpose": (end - 4.8, end - 3.1), "bow": (end - 1.8, end - 0.1)}  # 2 s holds, 1 s moves between
    record = calibrate_recording(acc, FPS, NAMES, NAMES, standard_segment_poses(NAMES, tuple(windows)),
                                 second_windows=windows)
    err = _errors(record, truth)
    assert max(err.values()) < 5.0, err
    assert err["left_forearm"] < 3.0 and err["right_forearm"] < 3.0 and err["chest"] < 3.0, err
    assert not any(s.reasons for s in record.sensors.values())


def test_a_long_sit_fixes_the_shanks_without_walking():
    """Sitting on the floor, legs straight out, lays the shank horizontal: gravity then shows its rotation about
    its own long axis (its standing heading) with sign. No walking at all: the still N-pose, then the sit."""
    from dataclasses import replace

    motion = standing_then_walking(sit_s=2.0, fps=FPS, seed=5)
    end = motion.n_frames / FPS
    nominal = standard_placements(motion.skeleton, NAMES)
    roll = np.diag([1.0, -1.0, -1.0])  # the right shin also rolled 180° about its X axis (along the bone)
    truth = [replace(p, rotation=p.rotation @ roll) if p.name == "right_shin" else p
             for p in mounted(nominal, seed=5)]
    acc = virtual_accelerometers(motion, truth) + np.random.default_rng(5).normal(0.0, 0.01, (motion.n_frames,
                                                                                              len(NAMES), 3))
    still = np.r_[0:int(2.5 * FPS), int((end - 1.8) * FPS):motion.n_frames]  # the N-pose, then the sit
    sit = (2.5 + 0.2, 2.5 + 1.9)
    record = calibrate_recording(acc[still], FPS, NAMES, NAMES, standard_segment_poses(NAMES, ("sit",)),
                                 second_windows={"sit": sit})
    err = _errors(record, truth)
    assert err["left_shin"] < 2.0 and err["right_shin"] < 2.0, err
    assert not record.sensors["left_shin"].reasons and record.sensors["left_shin"].passed
    shin = record.sensors["right_shin"]  # recovered, and failed as mounted far from nominal
    assert not shin.passed and any(re.search(r"mounted 1[5-9]\d deg away", r) for r in shin.reasons), shin.reasons


def test_without_heading_information_the_nominal_yaw_is_kept_and_said():
    acc, truth, motion = _take()
    still = acc[: int(2.5 * FPS)]
    record = calibrate_recording(still, FPS, NAMES, NAMES, standard_segment_poses(NAMES))
    assert all(any("heading about gravity not observed" in r for r in s.reasons) for s in record.sensors.values())


def test_flipped_sensor_is_flagged():
    acc, truth, _ = _take(flip=("left_shin",))
    record = calibrate_recording(acc, FPS, NAMES, NAMES, standard_segment_poses(NAMES))
    shin = record.sensors["left_shin"]
    assert not shin.passed and any("flipped" in r for r in shin.reasons)
    assert all(s.passed for n, s in record.sensors.items() if n != "left_shin")
    assert not record.passed


def test_no_quasi_static_stretch_is_refused():
    acc, _, _ = _take()
    with pytest.raises(ValueError, match="no quasi-static stretch"):
        calibrate_recording(acc[int(3.5 * FPS):], FPS, NAMES, NAMES, standard_segment_poses(NAMES))


def test_record_round_trip_and_reading_corrections(tmp_path, walking):
    record, truth, acc = walking
    path = tmp_path / "take.calibration.json"
    record.save(path)
    again = CalibrationRecord.load(path)
    assert again.config["method"] == "recording" and set(again.raw["still"]) == set(NAMES)
    data = load_sensor_calibration(path)
    skeleton = standing_then_walking().skeleton
    nominal = standard_placements(skeleton, NAMES)
    corrections = reading_corrections(nominal, data)
    # the corrected real readings are what the nominally mounted virtual sensors read (up to the calibration error)
    motion = standing_then_walking(fps=FPS)
    ideal = virtual_accelerometers(motion, nominal)
    real = virtual_accelerometers(motion, truth)
    for k, name in enumerate(NAMES):
        fixed = real[:, k] @ corrections[name].T
        before = np.median(np.sum((real[:, k] - ideal[:, k]) ** 2, axis=1))  # median: the clip joins spike
        after = np.median(np.sum((fixed - ideal[:, k]) ** 2, axis=1))
        assert after < 0.15 * before, (name, before, after)


def test_an_arm_sensor_rolled_180_degrees_about_the_bone_is_caught_by_the_t_pose():
    """The Bandai right-limb convention as a strapping error: in the N-pose the roll is a heading (invisible to
    gravity); the T-pose shows it as a ~180° correction, and the sensor fails."""
    from dataclasses import replace

    motion = standing_then_walking(tpose_s=2.0, fps=FPS, seed=4)
    nominal = standard_placements(motion.skeleton, NAMES)
    roll = np.diag([1.0, -1.0, -1.0])  # 180° about the sensor's X, which runs along the bone
    truth = [replace(p, rotation=p.rotation @ roll) if p.name == "right_forearm" else p for p in nominal]
    acc = virtual_accelerometers(motion, truth)
    end = motion.n_frames / FPS
    record = calibrate_recording(acc, FPS, NAMES, NAMES, standard_segment_poses(NAMES, ("tpose",)),
                                 second_windows={"tpose": (end - 1.8, end - 0.1)})
    arm = record.sensors["right_forearm"]
    assert arm.correction_deg > 170 and not arm.passed and any("mounted 18" in r for r in arm.reasons), arm
    assert rotation_angle_deg(arm.rotation @ truth[1].rotation.T) < 3.0


def _gateway_export(path, acc: np.ndarray, fps: float, keys: list[str]) -> None:
    """``acc`` (T, S, 3) written as `courtside gateway export --npz` lays a recording out: per live sensor its own
    samples and gateway times; here each sensor has its own rate (x-IMU3 100 Hz, Shimmer3 102.4 Hz), start and
    a 0.2 s dropout."""
    arrays = {}
    t_take = np.arange(len(acc)) / fps
    for k, key in enumerate(keys):
        rate = (100.0, 32768 / 320)[k % 2]
        t = np.arange(0.05 * k, t_take[-1], 1.0 / rate)
        gap = (t > 4.0 + 0.5 * k) & (t < 4.2 + 0.5 * k)
        t = t[~gap]
        arrays[f"{key}/t_host_s"] = 1000.0 + t
        arrays[f"{key}/acc_g"] = np.stack([np.interp(t, t_take, acc[:, k, a]) for a in range(3)], axis=1)
    np.savez(path, **arrays)


def test_calibrate_reads_a_gateway_recording_and_names_the_live_sensors(tmp_path, capsys):
    """`courtside calibrate EXPORT --sensor-map STATION/SENSOR=PLACEMENT`: devices bought off the shelf are one
    station each, so the record's sensor ids must be the live keys the console reads; the mountings are recovered
    as from an imported file (pelvis and shins; arms and chest keep the nominal heading and say so)."""
    from gateway.calibration.offline_cli import main

    acc, truth, _ = _take()
    keys = [f"{('ximu3-0000A00', 'shimmer3-R')[k % 2]}{k}/0" for k in range(len(NAMES))]
    _gateway_export(tmp_path / "rec.npz", acc, FPS, keys)
    out = tmp_path / "rec.calibration.json"
    assert main([str(tmp_path / "rec.npz"), "-o", str(out), "--sensor-map",
                 *(f"{key}={name}" for key, name in zip(keys, NAMES))]) == 0
    record = CalibrationRecord.load(out)
    assert set(record.sensors) == set(keys)
    by_segment = {s.segment: s for s in record.sensors.values()}
    err = {p.name: rotation_angle_deg(by_segment[p.name].rotation @ p.rotation.T) for p in truth}
    for name in ("lower_back", "left_shin", "right_shin"):
        assert err[name] < 4.0, err
    assert load_sensor_calibration(out).sensor_ids == dict(zip(NAMES, keys))  # what the console reads
    assert "left_shin, right_shin: heading from the walking swing plane" in capsys.readouterr().err  # sit hint
    with pytest.raises(MalformedFileError, match="--sensor-map STATION/SENSOR=PLACEMENT"):
        main([str(tmp_path / "rec.npz"), "-o", str(out)])
    with pytest.raises(MalformedFileError, match="does not hold"):
        main([str(tmp_path / "rec.npz"), "-o", str(out), "--sensor-map", "nosuch/0=chest"])
    with pytest.raises(CourtsideError, match="'left_knee' is not a standard placement"):
        main([str(tmp_path / "rec.npz"), "-o", str(out), "--sensor-map", f"{keys[0]}=left_knee"])


def test_calibrate_a_take_with_orientations_solves_each_sensor_s_yaw(tmp_path, capsys):
    """`courtside calibrate` on an import-imu take whose sensors also report orientations through the emulators'
    filter error model (random yaw per sensor, drift, walk, tilt noise), each strapped off nominal about an axis
    that is horizontal in the N-pose (so one pose sees all of it), standing still in the N-pose before walking:
    from the still windows, each sensor's yaw relative to the pelvis sensor is the emulated one within 1 deg,
    and its strapping the true one within the filter's mean tilt error over the stretch + 1 deg (one still pose
    cannot tell the two apart); the record keeps the orientations of the still windows."""
    from dataclasses import replace

    from engine.mocap import quaternions as quat
    from engine.mocap.orientation import virtual_orientations
    from gateway.calibration.offline_cli import main

    from .conftest import FILTER, tilt_rotation

    from engine.mocap.orientation_calibration import mean_orientation
    from engine.mocap.take_calibration import PoseSpec

    motion = standing_then_walking(fps=FPS, seed=6, sway_deg=0.0)
    poses = standard_segment_poses(NAMES)
    rng = np.random.default_rng(6)
    straps = {n: tilt_rotation(rng, quat.to_matrix(poses[n].orientation_wxyz).T @ [0.0, 1.0, 0.0], 20.0)
              for n in NAMES}  # sensor frame
    truth = [replace(p, rotation=p.rotation @ straps[p.name]) for p in standard_placements(motion.skeleton, NAMES)]
    acc = virtual_accelerometers(motion, truth) + rng.normal(0.0, 0.01, (motion.n_frames, len(NAMES), 3))
    errors = FILTER.draw(motion.n_frames, len(NAMES), FPS, rng)
    quats = errors.apply(virtual_orientations(motion, truth))
    np.savez(tmp_path / "take.npz", acc_g=acc, fps=FPS, sensor_names=np.array(NAMES), quat_wxyz=quats)
    out = tmp_path / "take.calibration.json"
    assert main([str(tmp_path / "take.npz"), "-o", str(out)]) == 0
    record = CalibrationRecord.load(out)
    yaw = np.array([record.sensors[n].orientation_yaw_rad for n in NAMES])
    known = errors.yaw_rad[int(1.5 * FPS)]  # the middle of the standing stretch
    pelvis = NAMES.index("lower_back")
    error = np.degrees(np.angle(np.exp(1j * ((yaw - yaw[pelvis]) - (known - known[pelvis])))))
    def angle_deg(a, b):
        return np.degrees(2 * np.arccos(np.minimum(1.0, np.abs(np.sum(a * b, axis=-1)))))

    strap_error = angle_deg(np.array([record.sensors[n].orientation_mount_wxyz for n in NAMES]),
                            quat.from_matrix(np.array([straps[n] for n in NAMES])))
    held = PoseSpec.parse(record.config["pose"])  # the still stretch found: the N-pose (an A-pose of 0 deg)
    assert held.name == "apose" and held.arm_deg == 0.0 and held.window_s[1] - held.window_s[0] >= 2.0
    i0, i1 = (int(round(t * FPS)) for t in held.window_s)
    tilt = angle_deg(mean_orientation(errors.tilt_wxyz[i0:i1]), quat.identity((len(NAMES),)))
    print("yaw relative to the pelvis, solved - emulated (deg):", np.round(error, 2),
          "strapping error (deg):", np.round(strap_error, 2), "the filter's mean tilt error (deg):", np.round(tilt, 2))
    assert np.abs(error).max() < 1.0 and (strap_error < tilt + 1.0).all()
    assert "orientation_yaw_deg" in capsys.readouterr().out
    t_raw, acc_raw, quat_raw = record.raw["still"]["chest"]
    assert quat_raw.shape == (len(t_raw), 4)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_with_a_database_every_orientation_sensor_s_accelerometer_takes_its_solved_strap(seed):
    """Straps uniform over all rotations, a walking take with orientations, calibrated against a database (the
    walks themselves): each sensor's accelerometer mounting is its placement's nominal rotation times the strap
    solved from the orientations (``R = N M``: one strap for both halves of the record), so the shins and the
    pelvis, whose walking axis would also give a heading, are within a few degrees of their true mounting. Before,
    the walking axis won and took its sign from the nominal mounting, which says nothing of a random strap: it
    turned them round."""
    from dataclasses import replace

    from engine.mocap import quaternions as quat
    from engine.mocap.orientation import OrientationErrorModel, virtual_orientations
    from engine.mocap.take_calibration import MotionPrior
    from gateway.calibration.recording import TakeStart

    motion = standing_then_walking(fps=FPS, seed=6, sway_deg=0.0)
    rng = np.random.default_rng(seed)
    straps = quat.to_matrix(quat.normalize(rng.normal(size=(len(NAMES), 4))))  # sensor -> nominal sensor frame
    truth = [replace(p, rotation=p.rotation @ m) for p, m in zip(standard_placements(motion.skeleton, NAMES), straps)]
    acc = virtual_accelerometers(motion, truth) + rng.normal(0.0, 0.01, (motion.n_frames, len(NAMES), 3))
    quats = OrientationErrorModel.magnetometer().apply(virtual_orientations(motion, truth), FPS, rng)
    prior = MotionPrior(virtual_orientations(motion, standard_placements(motion.skeleton, NAMES)), tuple(NAMES),
                        fps=FPS)
    poses = standard_segment_poses(NAMES)
    record = calibrate_recording(acc, FPS, NAMES, NAMES, poses, quat_wxyz=quats, take_start=TakeStart(prior=prior))
    for name in NAMES:
        s = record.sensors[name]
        strap = poses[name].nominal_rotation @ quat.to_matrix(np.asarray(s.orientation_mount_wxyz))
        assert rotation_angle_deg(s.rotation @ strap.T) < 1e-3, name
    err = _errors(record, truth)
    print("accelerometer mounting errors (deg):", {n: round(e, 1) for n, e in err.items()})
    for name in ("lower_back", "left_shin", "right_shin"):
        assert err[name] < 10.0, err
