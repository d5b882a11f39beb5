"""The standard set-up's calibration pose, against ground truth.

``CalibrationService.standard()`` (what the console's wizard uses) expects the reference N-pose. A still subject
standing in it with every seed-000 sensor strapped on tilted by a known 25-33 deg passes the placement check and
gets its mounting back within 2 deg; the same subject in a T-pose (the skeleton's zero pose) is refused by the
N-pose set-up, naming the forearm sensors, and accepted by the T-pose option."""
from __future__ import annotations

import numpy as np
import pytest

from engine.mocap import SEED000_SENSORS, Skeleton, joint_roles, standard_placements
from gateway.calibration import minimal_rotation, rotation_angle_deg
from gateway.calibration.pose import POSE_INSTRUCTIONS, reference_npose
from gateway.calibration.service import CalibrationService
from gateway.server import RequestError

from .conftest import RATE_HZ, Subject

DOWN = np.array([0.0, -1.0, 0.0])


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    return float(np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0))))


def _positions(skeleton: Skeleton, glob: np.ndarray) -> np.ndarray:
    pos = np.zeros((skeleton.n_joints, 3))
    for j in range(1, skeleton.n_joints):
        pos[j] = pos[skeleton.parents[j]] + glob[skeleton.parents[j]] @ skeleton.offsets_m[j]
    return pos


def test_reference_npose_geometry(skeleton):
    """Limbs straight down, trunk and feet as in the zero pose, palms in; how far it is from the T-pose."""
    roles = joint_roles(skeleton)
    local, glob = reference_npose(skeleton)
    pos = _positions(skeleton, glob)
    zero = skeleton.rest_positions()
    for side in ("left", "right"):
        for joint, distal in (("shoulder", "elbow"), ("elbow", "wrist"), ("hip", "knee"), ("knee", "ankle")):
            bone = pos[roles[f"{side}_{distal}"]] - pos[roles[f"{side}_{joint}"]]
            assert _angle_deg(bone, DOWN) < 1e-6, (side, joint)
        np.testing.assert_allclose(glob[roles[f"{side}_ankle"]], np.eye(3), atol=1e-9)  # foot flat as at rest
        # hands hang beside the thighs, feet under the hip joints
        assert abs(pos[roles[f"{side}_wrist"], 1] - pos[roles[f"{side}_hip"], 1]) < 0.15
        np.testing.assert_allclose(pos[roles[f"{side}_ankle"], [0, 2]], pos[roles[f"{side}_hip"], [0, 2]], atol=1e-9)
    for role in ("pelvis", "lower_back", "upper_back", "neck", "head"):
        np.testing.assert_allclose(glob[roles[role]], np.eye(3), atol=1e-12)
        np.testing.assert_allclose(pos[roles[role]], zero[roles[role]], atol=1e-12)
    # palms in: the arm sensors' Z axis (up in the T-pose, i.e. the back of the forearm) faces outwards
    for p in standard_placements(skeleton, ("left_forearm", "right_forearm")):
        outward = 1.0 if p.name.startswith("left") else -1.0
        np.testing.assert_allclose((glob[p.joint] @ p.rotation)[:, 2], [outward, 0.0, 0.0], atol=1e-9)
    # segment up (what the wizard aligns to) moves 90 deg on the forearms and 20 deg on the shins vs the T-pose
    placements = {p.name: p for p in standard_placements(skeleton, SEED000_SENSORS)}
    moved = {n: _angle_deg(glob[p.joint].T @ -DOWN, -DOWN) for n, p in placements.items()}
    print({n: round(a, 1) for n, a in moved.items()})
    for side in ("left", "right"):
        assert moved[f"{side}_forearm"] == pytest.approx(90.0, abs=0.5)
        assert moved[f"{side}_shin"] == pytest.approx(20.0, abs=0.5)
    assert moved["chest"] < 1e-6 and moved["lower_back"] < 1e-6


def test_a_skeleton_lying_down_is_refused(skeleton):
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # zero pose lying along -X
    lying = Skeleton(skeleton.names, skeleton.parents, skeleton.offsets_m @ turn.T, skeleton.end_site)
    with pytest.raises(ValueError, match="zero pose is not upright"):
        reference_npose(lying)


def _drive(service: CalibrationService, subject: Subject, t0: float, t1: float, rng) -> float:
    """Push [t0, t1) at RATE_HZ in 50 ms packets through the gateway hook, as station "st1"."""
    t_all = np.arange(t0, t1, 1.0 / RATE_HZ)
    for start in range(0, len(t_all), 5):
        t = t_all[start:start + 5]
        for sid in subject.segments:
            service.on_samples("st1", sid.split("/")[1], t, subject.samples(sid, t, rng))
    return t1


def _subject(specs, world_from_segment: dict | None, tilt_deg: tuple[float, float], seed: int) -> Subject:
    """Seed-000 sensors on station st1, each mounted nominally then tilted by uniform(*tilt_deg) degrees about a
    random axis perpendicular to the segment's up in the pose (the observable part), standing with its
    segments at ``world_from_segment`` (segment name -> world <- segment; None: the zero pose)."""
    rng = np.random.default_rng(seed)
    segments = {f"st1/{i}": name for i, name in enumerate(SEED000_SENSORS)}
    true_rotation = {}
    for sid, seg in segments.items():
        up = specs[seg].expected_up
        axis = np.cross(up, rng.normal(size=3))
        axis /= np.linalg.norm(axis)
        angle = np.radians(rng.uniform(*tilt_deg))
        tilt = minimal_rotation(up, np.cos(angle) * up + np.sin(angle) * np.cross(axis, up))
        true_rotation[sid] = tilt @ specs[seg].nominal_rotation
    bias = {sid: rng.normal(0.0, 0.01, 3) for sid in segments}
    pose = {} if world_from_segment is None else {sid: world_from_segment[seg] for sid, seg in segments.items()}
    return Subject(segments, true_rotation, bias, pose)


def _assign_and_check_placement(service: CalibrationService, subject: Subject, rng) -> tuple[bool, dict]:
    for sid, seg in subject.segments.items():
        service.handle("assign", {"sensor": sid, "segment": seg})
    assert service.handle("confirm", {})["accepted"]  # -> placement
    _drive(service, subject, 0.0, 0.5, rng)
    result = service.handle("confirm", {})
    return result["accepted"], result["state"]


def test_standard_setup_calibrates_a_subject_in_the_npose(npose_world):
    service = CalibrationService.standard()
    specs = service.wizard.segments
    state = service.state()
    assert state["pose"] == "npose" and state["pose_instructions"] == POSE_INSTRUCTIONS["npose"]
    assert "arms straight down" in state["pose_instructions"]
    subject = _subject(specs, npose_world, (25.0, 33.0), seed=21)
    rng = np.random.default_rng(22)
    accepted, state = _assign_and_check_placement(service, subject, rng)
    tilts = {sid: s["tilt_deg"] for sid, s in state["sensors"].items()}
    print("placement tilts (deg):", {sid: round(v, 1) for sid, v in tilts.items()})
    assert accepted, state["messages"]
    assert all(s["placement_ok"] for s in state["sensors"].values()) and len(tilts) == 6
    assert all(24.0 < v < 35.0 for v in tilts.values())  # the true tilts, seen by the check
    t = 0.5
    while service.state()["step"] == "npose" and t < 10:
        t = _drive(service, subject, t, t + 0.25, rng)
    assert service.state()["step"] == "tap"
    for sid, result in service.wizard.results.items():
        error = rotation_angle_deg(result.rotation @ subject.true_rotation[sid].T)
        mounting = rotation_angle_deg(specs[subject.segments[sid]].nominal_rotation @ subject.true_rotation[sid].T)
        print(f"{sid} ({subject.segments[sid]}): mounted {mounting:.1f} deg off nominal, recovered within "
              f"{error:.2f} deg")
        assert error < 2.0 and mounting > 24.0 and result.passed


def test_standard_setup_refuses_a_subject_in_the_tpose_naming_the_sensors():
    service = CalibrationService.standard()
    specs = service.wizard.segments
    subject = _subject(specs, None, (0.0, 0.0), seed=31)  # perfectly strapped, but arms out (zero pose)
    accepted, state = _assign_and_check_placement(service, subject, np.random.default_rng(32))
    assert not accepted and state["step"] == "placement"
    message = state["messages"][-1]
    print(message)
    assert message.startswith("placement check failed")
    for sid in ("st1/0", "st1/1"):  # the forearms: 90 deg off
        assert f"{sid} ({subject.segments[sid]}): tilted 90 deg" in message
        assert state["sensors"][sid]["placement_ok"] is False
        assert "holds the N-pose (arms down)" in state["sensors"][sid]["placement_reasons"][0]
    for sid in ("st1/4", "st1/5"):  # trunk: the same in both poses
        assert state["sensors"][sid]["placement_ok"] and state["sensors"][sid]["tilt_deg"] < 2.0
    # the T-pose option accepts the same subject
    tpose = CalibrationService.standard(pose="tpose")
    assert tpose.state()["pose"] == "tpose"
    accepted, state = _assign_and_check_placement(tpose, subject, np.random.default_rng(33))
    assert accepted, state["messages"]
    assert tpose.handle("reset", {})["pose"] == "tpose"  # a fresh wizard keeps the pose


def test_unknown_pose_is_refused():
    with pytest.raises(ValueError, match="unknown calibration pose 'lpose'"):
        CalibrationService.standard(pose="lpose")
    with pytest.raises(RequestError):
        CalibrationService.standard().handle("assign", {"sensor": "st1/0", "segment": "tail"})


def test_the_zero_pose_setup_would_refuse_the_npose_subject(npose_world):
    """The defect this set-up fixes: assuming the zero pose (T-pose) refuses a subject in a real N-pose."""
    service = CalibrationService.standard(pose="tpose")
    subject = _subject(CalibrationService.standard().wizard.segments, npose_world, (0.0, 0.0), seed=41)
    accepted, state = _assign_and_check_placement(service, subject, np.random.default_rng(42))
    tilts = {subject.segments[sid]: round(s["tilt_deg"], 1) for sid, s in state["sensors"].items()}
    print("T-pose set-up, subject in the N-pose, tilts (deg):", tilts)
    assert not accepted
    assert tilts["left_forearm"] == pytest.approx(90.0, abs=1.0) and tilts["left_shin"] == pytest.approx(20.0, abs=1.0)


def test_the_wizard_s_orientation_template_is_its_pose_on_the_console_s_skeleton(skeleton):
    """What an orientation sensor's reading is solved against (`SegmentSpec.pose_orientation_wxyz`, and `courtside
    calibrate`'s `SegmentPose.orientation_wxyz`) is the nominal sensor's orientation in the reference N-pose built
    on the shipped CMU skeleton, the pose whose `expected_up` the accelerometers are calibrated against (so both
    halves of a record describe one strap). The evaluation's template (`pose_sensor_orientations`, the same pose
    built on the T-pose re-based skeleton) is the same for limbs and pelvis; the chest differs by the CMU zero
    pose's 2.7 deg trunk lean."""
    from engine.mocap import quaternions
    from engine.mocap.orientation_calibration import pose_sensor_orientations
    from gateway.calibration.recording import standard_segment_poses

    glob = reference_npose(skeleton)[1]
    specs = CalibrationService.standard().wizard.segments
    poses = standard_segment_poses(list(SEED000_SENSORS))
    engine = pose_sensor_orientations(skeleton, SEED000_SENSORS)
    for k, p in enumerate(standard_placements(skeleton, SEED000_SENSORS)):
        want = quaternions.from_matrix(glob[p.joint] @ p.rotation)
        for got in (specs[p.name].pose_orientation_wxyz, poses[p.name].orientation_wxyz):
            assert abs(np.dot(got, want)) == pytest.approx(1.0, abs=1e-12), p.name
        np.testing.assert_allclose(quaternions.to_matrix(want).T @ [0.0, 1.0, 0.0],
                                   p.rotation.T @ specs[p.name].expected_up, atol=1e-12)  # up, as the accelerometer
        off_deg = np.degrees(2 * np.arccos(min(1.0, abs(np.dot(want, engine[k])))))
        assert off_deg == pytest.approx(2.7 if p.name == "chest" else 0.0, abs=0.05), (p.name, off_deg)
