"""`courtside calibrate --graph` (issue 29): a record for the graph in use, any strapping, a start pose found
from the tilts; `synthesize --graph --calibration` takes it, converts a record made for other joint frames and
refuses, in one line naming both skeletons, one it cannot convert. Bandai gestures (skipped without the shared
mocap)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from engine.errors import CourtsideError, UsageError
from engine.graph.cli import build_graph_main, synthesize_main
from engine.mocap import SEED000_SENSORS, read_bvh, resample, standard_placements, virtual_accelerometers
from engine.mocap import quaternions as quat
from engine.mocap.orientation import OrientationErrorModel, virtual_orientations
from engine.mocap.orientation_calibration import pose_sensor_orientations
from gateway.calibration import CalibrationRecord
from gateway.calibration.offline_cli import main as calibrate_main

NAMES = list(SEED000_SENSORS)
FPS = 30.0
PATTERN = "bandai-namco-1/data/dataset-1_bye_*_00[12].bvh"


@pytest.fixture(scope="module")
def bandai(shared_mocap, tmp_path_factory):
    """A graph of Bandai "bye" clips, and a take of one of them as six strapped orientation sensors would give it:
    2 s held in an A-pose (arms 60 deg out), then the clip; every strap a rotation uniform over all rotations."""
    tmp = tmp_path_factory.mktemp("bandai")
    assert build_graph_main(["--mocap-dir", str(shared_mocap), "--pattern", PATTERN, "-o", str(tmp / "g.npz")]) == 0
    motion = resample(read_bvh(sorted(shared_mocap.glob(PATTERN))[0]), FPS)
    placements = standard_placements(motion.skeleton, NAMES)
    rng = np.random.default_rng(29)
    strap = quat.normalize(rng.normal(size=(len(NAMES), 4)))
    held = pose_sensor_orientations(motion.skeleton, NAMES, "apose", arm_deg=60.0)
    n_held = int(2 * FPS)
    world = np.concatenate([np.repeat(held[None], n_held, 0), virtual_orientations(motion, placements)])
    world = quat.multiply(world, strap[None])  # the strapped sensors' orientations
    acc_nominal = np.concatenate([np.repeat(quat.rotate(quat.conjugate(held), [0.0, 1.0, 0.0])[None], n_held, 0),
                                  virtual_accelerometers(motion, placements)])
    acc = quat.rotate(quat.conjugate(strap)[None], acc_nominal) + rng.normal(0.0, 0.01, acc_nominal.shape)
    quats = OrientationErrorModel(yaw_offset=True).apply(world, FPS, rng)
    np.savez(tmp / "take.npz", acc_g=acc, fps=FPS, sensor_names=np.array(NAMES), quat_wxyz=quats)
    return tmp, motion.skeleton


def test_a_record_for_the_graph_in_use_with_any_strapping(bandai, capsys):
    tmp, skeleton = bandai
    rec = tmp / "take.calibration.json"
    assert calibrate_main([str(tmp / "take.npz"), "--graph", str(tmp / "g.npz"), "-o", str(rec)]) == 0
    record = CalibrationRecord.load(rec)
    assert record.skeleton["name"] == "g.npz" and record.skeleton["joints"] == skeleton.n_joints
    pose = record.config["pose"]
    assert pose.startswith("apose:") and abs(float(pose.split(":")[1].split("@")[0]) - 60.0) <= 10.0, pose
    assert record.config["north"] == "own"  # a 6-axis filter: every sensor's own north, found so (auto)
    # what decided it, and the flag that overrides it, in one line for the user who knows the filter
    note = [line for line in capsys.readouterr().err.splitlines() if line.startswith("calibrate: note: north own")]
    assert len(note) == 1 and "deg from following the pelvis" in note[0] and "--north shared" in note[0], note
    assert "deg from following the pelvis" in record.config["north_basis"]
    assert record.passed  # no sensor failed for its mounting, though every strap is far from nominal
    assert not any("flipped" in r or "limit" in r for s in record.sensors.values() for r in s.reasons)
    assert max(s.correction_deg for s in record.sensors.values()) > 90.0
    capsys.readouterr()
    out = tmp / "out.bvh"
    assert synthesize_main(["--graph", str(tmp / "g.npz"), "--input", str(tmp / "take.npz"), "--calibration", str(rec),
                            "-o", str(out)]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["segment_posing"] == "calibrated yaw"


def test_a_record_for_other_joint_frames_is_converted_or_refused_naming_both(bandai, capsys):
    tmp, _ = bandai
    cmu = tmp / "cmu.calibration.json"  # made for the shipped CMU skeleton
    assert calibrate_main([str(tmp / "take.npz"), "-o", str(cmu)]) == 0
    args = ["--graph", str(tmp / "g.npz"), "--input", str(tmp / "take.npz"), "-o", str(tmp / "x.bvh")]
    capsys.readouterr()
    assert synthesize_main(args + ["--calibration", str(cmu)]) == 0  # converted through each strap
    doc = json.loads(cmu.read_text())
    for entry in doc["sensors"].values():  # as a record from before the straps were kept, rotated off its frames
        del entry["strap_wxyz"]
        entry["rotation"] = (np.diag([1.0, -1.0, -1.0]) @ np.asarray(entry["rotation"])).tolist()
    old = tmp / "old.calibration.json"
    old.write_text(json.dumps(doc))
    assert synthesize_main(args + ["--calibration", str(old)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "the shipped CMU skeleton" in err and "the graph's skeleton" in err, err


def test_bad_takes_are_one_line(bandai, tmp_path):
    tmp, _ = bandai
    with np.load(tmp / "take.npz") as data:
        take = dict(data)
    zero = dict(take, quat_wxyz=np.where(np.arange(len(NAMES))[None, :, None] == 2, 0.0, take["quat_wxyz"]))
    moving = {k: (v[int(2 * FPS):] if k in ("acc_g", "quat_wxyz") else v) for k, v in take.items()}
    for name, arrays, problem in (("zero", zero, "not unit"),
                                  ("moving", moving, "no (quasi-static|still) stretch")):
        np.savez(tmp_path / f"{name}.npz", **arrays)
        with pytest.raises(CourtsideError, match=problem) as caught:
            calibrate_main([str(tmp_path / f"{name}.npz"), "--graph", str(tmp / "g.npz"), "-o",
                            str(tmp_path / f"{name}.calibration.json")])
        assert "\n" not in str(caught.value)
    with pytest.raises(UsageError, match="--north: invalid choice: 'magnetic'"):
        calibrate_main([str(tmp / "take.npz"), "--north", "magnetic", "-o", str(tmp_path / "m.calibration.json")])
    assert not (tmp_path / "m.calibration.json").exists()
    with pytest.raises(CourtsideError, match="--pose none .* give --graph"):
        calibrate_main([str(tmp / "take.npz"), "--pose", "none", "-o", str(tmp_path / "n.calibration.json")])
