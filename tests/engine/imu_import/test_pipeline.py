"""Done-when of issue 15: a real-format file in each supported format goes import-imu -> calibrate ->
synthesize -> BVH in three `courtside` commands (real subprocesses), with sensors strapped 20-30° off nominal."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from engine.mocap import SEED000_SENSORS, read_bvh, standard_placements
from gateway.calibration import rotation_angle_deg
from gateway.calibration.record import CalibrationRecord

from bench.support.imu_formats import mounted, standing_then_walking, virtual_recording, write_generic_csv, write_mvnx, \
    write_ximu3_logger

NAMES = list(SEED000_SENSORS)


def courtside(*args: str) -> dict:
    proc = subprocess.run([sys.executable, "-m", "gateway.cli", *args], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pipeline")
    motion = standing_then_walking(walks=("16_11", "16_16"), tpose_s=2.0, bow_s=2.0, fps=100.0)
    truth_placements = mounted(standard_placements(motion.skeleton, NAMES))
    courtside("build-graph", "--sample", "-o", str(tmp / "graph.npz"))
    return tmp, motion, virtual_recording(motion, truth_placements), truth_placements


def _write(fmt: str, tmp, truth) -> list[str]:
    if fmt == "csv":
        cols = write_generic_csv(tmp / "take.csv", truth, "m/s2", "xyzw", ",", "ms")
        args = [str(tmp / "take.csv"), "--time", "time", "--time-unit", "ms"]
        for name, (acc, q) in cols.items():
            args += ["--sensor", f"{name}={','.join(acc)}", "--quat", f"{name}={','.join(q)}"]
        return args
    if fmt == "xsens":
        write_mvnx(tmp / "take.mvnx", truth)
        return [str(tmp / "take.mvnx")]
    root = write_ximu3_logger(tmp / "logged", truth, [f"{0x1A2B3C40 + k:08X}" for k in range(len(NAMES))],
                              ["x-IMU3"] * len(NAMES), [5_000 * k for k in range(len(NAMES))])
    args = [str(root)]
    for k, name in enumerate(NAMES):
        args += ["--sensor-map", f"{0x1A2B3C40 + k:08X}={name}"]
    return args


@pytest.mark.parametrize("fmt", ["csv", "xsens", "ximu3"])
def test_three_commands_to_bvh(setup, fmt):
    tmp, motion, truth, placements = setup
    out = tmp / fmt
    out.mkdir()
    imported = courtside("import-imu", *_write(fmt, out, truth), "--format", fmt, "-o", str(out / "take.npz"))
    assert set(imported["sensors"].values()) == set(NAMES)
    if fmt != "ximu3":  # csv/xsens files are in m/s2 and are converted
        assert set(imported["units"].values()) == {"m/s2"}
    end_s = motion.duration_s
    cal = courtside("calibrate", str(out / "take.npz"), "-o", str(out / "take.calibration.json"),
                    "--second-pose", f"tpose@{end_s - 4.8:.2f}:{end_s - 3.1:.2f}",
                    "--second-pose", f"bow@{end_s - 1.8:.2f}:{end_s - 0.1:.2f}")
    record = CalibrationRecord.load(out / "take.calibration.json")
    by_segment = {s.segment: s.rotation for s in record.sensors.values()}
    errors = {p.name: rotation_angle_deg(by_segment[p.name] @ p.rotation.T) for p in placements}
    # arms from the T-pose, trunk from the bow, shins from walking
    assert max(errors.values()) < 5.0 and cal["passed"], errors
    syn = courtside("synthesize", "--graph", str(tmp / "graph.npz"), "--input", str(out / "take.npz"),
                    "--calibration", str(out / "take.calibration.json"), "-o", str(out / "take.bvh"))
    bvh = read_bvh(out / "take.bvh")
    assert bvh.n_frames == syn["samples"] == pytest.approx(motion.duration_s * 30, abs=2)
    assert np.all(np.isfinite(bvh.root_positions_m))


def test_import_refuses_stated_g_on_metres_per_second_squared(setup):
    tmp, _, truth, _ = setup
    args = _write("csv", tmp, truth)
    proc = subprocess.run([sys.executable, "-m", "gateway.cli", "import-imu", *args, "--format", "csv", "--units", "g",
                           "-o", str(tmp / "never.npz")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "the data is in m/s2" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp / "never.npz").exists()


def test_commands_report_bad_paths_in_one_line(setup, tmp_path):
    tmp, _, truth, _ = setup
    args = _write("csv", tmp_path, truth)
    for command in (["import-imu", *args, "--format", "csv", "-o", str(tmp_path / "missing" / "t.npz")],
                    ["calibrate", str(tmp_path / "missing.npz"), "-o", str(tmp_path / "r.json")],
                    ["import-imu", str(tmp_path / "take.csv"), "--format", "ximu3", "-o", str(tmp_path / "t.npz")]):
        proc = subprocess.run([sys.executable, "-m", "gateway.cli", *command], capture_output=True, text=True,
                              timeout=120)
        assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1 and "courtside" in proc.stderr


def test_reconstruct_reads_an_imported_take_in_its_own_sensor_order(setup, tmp_path):
    """`courtside reconstruct --method hmm` on an imported x-IMU3 take (gyro included): the HMM's IMUs are taken
    by name from a take that lists more sensors, in another order."""
    _, motion, truth, _ = setup
    args = _write("ximu3", tmp_path, truth)
    courtside("import-imu", *args, "--format", "ximu3", "-o", str(tmp_path / "take.npz"))
    out = courtside("reconstruct", "--method", "hmm", "--sample", "--imus", "right_shin", "left_shin",
                    "--input", str(tmp_path / "take.npz"), "-o", str(tmp_path / "hmm.bvh"))
    assert out["frames"] == read_bvh(tmp_path / "hmm.bvh").n_frames > 0.9 * motion.duration_s * 30


def test_an_xsens_export_is_calibrated_in_one_north_and_says_why(setup, tmp_path):
    """Xsens filters reference every sensor's heading to local magnetic north, so `calibrate --north auto` takes one
    north for a take imported with --format xsens, says so on stderr with the override, and keeps it out of the
    way of `--north own`; the same readings as a generic CSV are left to the tests (here, without a database, a
    north each)."""
    from bench.support.imu_formats import write_mt_exports

    _, _, truth, _ = setup
    ids = [f"00B42D{k:02X}" for k in range(len(NAMES))]
    write_mt_exports(tmp_path / "mt", truth, ids)
    courtside("import-imu", str(tmp_path / "mt"), "--format", "xsens", *(f"--sensor-map={i}={n}" for i, n in
                                                                         zip(ids, NAMES)), "-o", str(tmp_path / "x.npz"))
    courtside("import-imu", *_write("csv", tmp_path, truth), "--format", "csv", "-o", str(tmp_path / "c.npz"))

    def calibrate(take: str, *extra: str) -> tuple[CalibrationRecord, str]:
        proc = subprocess.run([sys.executable, "-m", "gateway.cli", "calibrate", str(tmp_path / take), "-o",
                               str(tmp_path / f"{take}.json"), *extra], capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        return CalibrationRecord.load(tmp_path / f"{take}.json"), proc.stderr

    record, err = calibrate("x.npz")
    assert record.config["north"] == "shared" and "an Xsens export" in record.config["north_basis"]
    assert "calibrate: note: north shared (an Xsens export" in err and "pass --north own" in err, err
    record, err = calibrate("x.npz", "--north", "own")
    assert record.config["north"] == "own" and "north_basis" not in record.config and "note: north" not in err
    record, err = calibrate("c.npz")
    assert record.config["north"] == "own" and "north_basis" not in record.config
