"""Joint centres down a segment tree: an exact synthetic chain, the real biobuddy hip/knee trials and a CMU trial.
The end-to-end pipeline (label → fit-skeleton → BVH → build-graph) is in test_pipeline_real_takes.py."""
from __future__ import annotations

import numpy as np

from engine.mocap import read_c3d
from engine.skeleton_fit.cli import main as fit_main, subject_markers
from engine.skeleton_fit.frames import frame_from_three, to_local
from engine.skeleton_fit.gdke import JointType, fit_joint
from engine.skeleton_fit.markerset import MarkerSet, SegmentSpec, detect_marker_set
from engine.skeleton_fit.model import fit_skeleton


def _rotations(rng, n, max_angle):
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    angle = rng.uniform(0, max_angle, n)
    k = np.zeros((n, 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    k -= np.swapaxes(k, 1, 2)
    return np.eye(3) + np.sin(angle)[:, None, None] * k + (1 - np.cos(angle))[:, None, None] * k @ k


CHAIN = MarkerSet("chain", (SegmentSpec("root", None, ("r0", "r1", "r2")), SegmentSpec("child", "root", ("c0", "c1", "c2"))))


def _chain(rng, hinge: bool, frames=100, noise_m=0.001):
    """Root with random 6-DOF motion; child rotating about a joint at a known root-local point."""
    root_local = np.array([[0.1, 0, 0], [-0.1, 0.05, 0], [0, -0.08, 0.06]])
    joint_local = np.array([0.05, -0.2, 0.03])
    child_local = np.array([[0.0, -0.35, 0.0], [0.05, -0.3, 0.02], [-0.04, -0.38, 0.03]])
    root_rot = _rotations(rng, frames, np.pi)
    root_pos = rng.uniform(-1, 1, (frames, 3))
    if hinge:
        angle = rng.uniform(0, 2.0, frames)
        c, s = np.cos(angle), np.sin(angle)
        rel = np.zeros((frames, 3, 3))
        rel[:, 0, 0], rel[:, 1, 1], rel[:, 1, 2], rel[:, 2, 1], rel[:, 2, 2] = 1, c, -s, s, c  # about root-local x
    else:
        rel = _rotations(rng, frames, 1.2)
    markers = {}
    for name, p in zip(("r0", "r1", "r2"), root_local):
        markers[name] = root_pos + root_rot @ p
    for name, p in zip(("c0", "c1", "c2"), child_local):
        markers[name] = root_pos + np.einsum("fij,fj->fi", root_rot, joint_local + rel @ p)
    for name in markers:
        markers[name] = markers[name] + rng.normal(0, noise_m, (frames, 3))
    return markers, joint_local


def test_root_frames_are_orthonormal_and_rigid():
    markers, _ = _chain(np.random.default_rng(1), hinge=False, noise_m=0.0)
    origin, rot = frame_from_three(markers["r0"], markers["r1"], markers["r2"])
    assert np.allclose(rot @ np.swapaxes(rot, 1, 2), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(rot), 1.0)
    local = to_local(markers["r1"], origin, rot)
    assert np.allclose(local, local[0], atol=1e-12)


def test_ball_joint_centre_recovered_to_eq7_accuracy():
    errors = []
    for seed in range(20):
        markers, joint_local = _chain(np.random.default_rng(seed), hinge=False)
        model = fit_skeleton(markers, CHAIN)
        child = model.joints[1]
        assert child.fit.kind is JointType.BALL
        errors.append(np.linalg.norm(child.centre_local - _true_centre_local(joint_local)))
    # 3 markers x 100 frames with 1 mm noise on every marker (child and root): a few 3σ/√N, well under 2 mm
    assert np.median(errors) < 0.002


def _true_centre_local(joint_local):
    """The joint in the fitted root frame (centroid origin), from the noise-free definition r_local."""
    root_local = np.array([[0.1, 0, 0], [-0.1, 0.05, 0], [0, -0.08, 0.06]])
    origin, rot = frame_from_three(*root_local[:, None, :])
    return to_local(joint_local[None], origin, rot)[0]


def test_hinge_joint_is_classified_and_axis_recovered():
    markers, joint_local = _chain(np.random.default_rng(3), hinge=True)
    model = fit_skeleton(markers, CHAIN)
    child = model.joints[1]
    assert child.fit.kind is JointType.HINGE
    root_local = np.array([[0.1, 0, 0], [-0.1, 0.05, 0], [0, -0.08, 0.06]])
    _, rot = frame_from_three(*root_local[:, None, :])
    true_axis = rot[0].T @ np.array([1.0, 0, 0])  # root-local x in the fitted frame
    assert abs(child.axis_local @ true_axis) > 0.99
    centre = _true_centre_local(joint_local)
    off_axis = (child.centre_local - centre) - ((child.centre_local - centre) @ true_axis) * true_axis
    assert np.linalg.norm(off_axis) < 0.005


def _harrington_hip(m):
    """Harrington et al. 2007 regression: hip centre from pelvis width/depth (mid-ASIS origin), metres."""
    rasis, lasis, rpsis, lpsis = (np.nanmean(m[k], axis=0) for k in ("RASIS", "LASIS", "RPSIS", "LPSIS"))
    mid_asis, mid_psis = (rasis + lasis) / 2, (rpsis + lpsis) / 2
    z = (rasis - lasis) / np.linalg.norm(rasis - lasis)  # right
    x = mid_asis - mid_psis
    x -= (x @ z) * z
    x /= np.linalg.norm(x)  # anterior
    y = np.cross(z, x)  # superior
    pw, pd = np.linalg.norm(rasis - lasis) * 1000, np.linalg.norm(mid_asis - mid_psis) * 1000
    local_mm = np.array([-0.24 * pd - 9.9, -0.30 * pw - 10.9, 0.33 * pw + 7.3])
    return mid_asis + (np.stack([x, y, z], 1) @ local_mm) / 1000


def test_real_hip_trial_centre_is_plausible_and_knee_is_a_hinge(shared_mocap):
    hip = read_c3d(shared_mocap / "markers" / "biobuddy_right_hip.c3d")
    m = {k: hip.positions_m[:, i] for i, k in enumerate(hip.labels)}
    origin, rot = frame_from_three(m["RASIS"], m["LASIS"], m["RPSIS"])
    thigh = [to_local(m[k], origin, rot) for k in ("RTHI1", "RTHI2", "RTHI3", "RLFE", "RMFE")]
    fit = fit_joint(thigh)
    assert fit.kind is JointType.BALL
    centre_world = origin + rot @ fit.centre  # (F,3): the fitted centre through the trial
    gap = np.linalg.norm(np.nanmean(centre_world, axis=0) - _harrington_hip({k: m[k] for k in m}))
    print(f"\nhip centre vs Harrington regression: {1000 * gap:.1f} mm (kappa {fit.kappa:.1f})")
    assert gap < 0.03
    knee = read_c3d(shared_mocap / "markers" / "biobuddy_right_knee.c3d")
    m = {k: knee.positions_m[:, i] for i, k in enumerate(knee.labels)}
    origin, rot = frame_from_three(m["RTHI1"], m["RTHI2"], m["RTHI3"])
    shank = [to_local(m[k], origin, rot) for k in ("RLEG1", "RLEG2", "RLEG3", "RLM", "RSPH")]
    knee_fit = fit_joint(shank)
    epicondyles = np.nanmean(to_local((m["RLFE"] + m["RMFE"]) / 2, origin, rot), axis=0)
    assert knee_fit.kind is JointType.HINGE
    off_axis = (epicondyles - knee_fit.centre) - ((epicondyles - knee_fit.centre) @ knee_fit.axis) * knee_fit.axis
    print(f"knee kappa {knee_fit.kappa:.0f}; axis passes {1000 * np.linalg.norm(off_axis):.1f} mm from the "
          f"epicondyle midpoint")
    assert np.linalg.norm(off_axis) < 0.03


def test_fit_skeleton_cli_reports_bad_input(tmp_path, capsys):
    bad = tmp_path / "bad.c3d"
    bad.write_bytes(b"not a c3d")
    assert fit_main([str(bad), "-o", str(tmp_path / "x.bvh")]) == 2
    assert "bad.c3d" in capsys.readouterr().err


def test_real_cmu_skeleton_has_steady_plausible_bones(shared_mocap):
    """Spec 002 §5.12 sanity check on a CMU 41-marker trial: bone lengths between consecutive joint centres vary
    by at most ~2 cm over the trial, and thigh, shank and upper arm have human lengths."""
    data = read_c3d(shared_mocap / "markers" / "cmu_135_02.c3d")
    markers = subject_markers(data.labels, data.positions_m, None)
    model = fit_skeleton(markers, detect_marker_set(list(markers)))
    centres = model.joint_positions(markers)
    lengths = {j.segment: np.linalg.norm(centres[j.segment] - centres[j.parent], axis=1) for j in model.joints[1:]}
    assert all(np.nanstd(v) < 0.02 for v in lengths.values())
    for bone in ("LowerLeg_L", "LowerLeg_R", "Foot_L", "Foot_R"):  # hip→knee and knee→ankle
        assert 0.35 < np.nanmean(lengths[bone]) < 0.5
    for bone in ("LowerArm_L", "LowerArm_R"):  # shoulder→elbow
        assert 0.25 < np.nanmean(lengths[bone]) < 0.4
