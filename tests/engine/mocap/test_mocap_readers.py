"""Readers and writer: real files load with the right units/axes, round trips are exact, bad files fail
with MalformedFileError naming file, line and problem."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import engine.mocap as M
from engine.errors import MalformedFileError
from engine.mocap import quaternions as quat


def _height(motion: M.Motion) -> float:
    pos, _ = M.forward_kinematics(motion)
    return float(np.max(pos[..., 1].max(axis=1) - pos[..., 1].min(axis=1)))


def test_shipped_asf_amc_clip_is_a_standing_human_in_metres_y_up():
    motion = M.load_clip(M.sample_clips()["16_16"])
    assert motion.fps == 120 and motion.n_frames == 510
    assert 1.55 < _height(motion) < 1.9
    pos, _ = M.forward_kinematics(motion)
    roles = M.joint_roles(motion.skeleton)
    assert np.all(pos[:, roles["head"], 1] > pos[:, roles["pelvis"], 1] + 0.3)  # head above pelvis: Y up
    assert np.percentile(pos[:, roles["left_toe"], 1], 5) == pytest.approx(0.03, abs=0.05)  # feet on y = 0
    speed = np.linalg.norm(np.diff(motion.root_positions_m[:, [0, 2]], axis=0), axis=1).mean() * motion.fps
    assert 0.8 < speed < 1.5  # a walk, in m/s


def test_asf_rotation_convention_matches_the_raw_cmu_markers(shared_mocap):
    """Every marker of the raw C3D of the same take rides rigidly on the anatomically right segment."""
    motion = M.read_amc(shared_mocap / "cmu-amc/135/135_02.amc", shared_mocap / "cmu-amc/135/135.asf")
    markers = M.read_c3d(shared_mocap / "markers/cmu_135_02.c3d")
    assert markers.n_frames == motion.n_frames
    pos, glob = M.forward_kinematics(motion)
    pos, glob, x = pos[::5], glob[::5], markers.positions_m[::5]
    labels = [l.split(":")[-1] for l in markers.labels]
    waist = x[:, [labels.index(n) for n in ("LFWT", "RFWT", "LBWT", "RBWT")]].mean(axis=1)
    # similarity transform lab frame -> AMC world (Umeyama), fitted on the pelvis only
    a0, b0 = waist.mean(0), pos[:, 0].mean(0)
    u, s, vt = np.linalg.svd((pos[:, 0] - b0).T @ (waist - a0))
    d = np.diag([1, 1, np.sign(np.linalg.det(u @ vt))])
    rot, scale = u @ d @ vt, (s * np.diag(d)).sum() / ((waist - a0) ** 2).sum()
    assert scale == pytest.approx(1.0, abs=0.02)  # the ASF length unit conversion is right
    x = (x - a0) @ rot.T * scale + b0
    expected = {"LANK": "ltibia", "RSHN": "rtibia", "LHEE": "lfoot", "RHEE": "rfoot", "LTHI": "lfemur",
                "RTHI": "rfemur", "LFRM": "lradius", "RELB": "rradius", "LWRA": "lwrist", "RWRA": "rwrist",
                "LUPA": "lhumerus", "RUPA": "rhumerus", "LFHD": "head", "LBWT": "root"}
    for label, segment in expected.items():
        k = labels.index(label)
        local = np.einsum("fjki,fjk->fji", glob, x[:, k:k + 1] - pos)  # marker in every joint frame
        spread = np.linalg.norm(local.std(axis=0), axis=-1)
        best = int(np.argmin(spread))
        if motion.skeleton.end_site[best]:  # an end site moves with its parent's segment
            best = int(motion.skeleton.parents[best])
        assert motion.skeleton.names[best] == segment, label
        assert spread.min() < 0.05, label


def test_cmu_bvh_units_give_a_human_sized_skeleton(shared_mocap):
    motion = M.read_bvh(shared_mocap / "cmu-bvh/131_01.bvh")
    assert motion.fps == pytest.approx(120, rel=1e-3)
    explicit = M.read_bvh(shared_mocap / "cmu-bvh/131_01.bvh", scale="cmu")
    np.testing.assert_allclose(motion.skeleton.offsets_m, explicit.skeleton.offsets_m)
    assert M.CMU_UNIT_M == pytest.approx(0.0564444, rel=1e-5)
    assert 1.4 < _height(motion) < 1.9
    roles = M.joint_roles(motion.skeleton)
    assert motion.skeleton.names[roles["left_knee"]] == "LeftKnee"


def test_bandai_clip_loads_y_up_in_metres_with_merged_root(shared_mocap):
    path = shared_mocap / "bandai-namco-1/data/dataset-1_walk_normal_001.bvh"
    motion = M.read_bvh(path)
    assert motion.fps == pytest.approx(30, rel=1e-3)
    assert motion.skeleton.names[0] == "Hips" and "joint_Root" not in motion.skeleton.names
    assert 1.2 < _height(motion) < 1.9
    raw = path.read_text().splitlines()
    first = np.array(raw[raw.index("MOTION") + 3].split(), float)
    # joint_Root channels are all zero, so the Hips position channels (cm) are the world root position
    np.testing.assert_allclose(motion.root_positions_m[0], first[6:9] / 100)
    pos, _ = M.forward_kinematics(motion)
    roles = M.joint_roles(motion.skeleton)
    assert np.all(pos[:, roles["head"], 1] > pos[:, roles["pelvis"], 1] + 0.3)
    contacts = M.foot_contacts(motion)
    assert 0.4 < contacts.mean() < 0.85


def test_bvh_round_trip_is_exact_on_a_real_clip(tmp_path):
    motion = M.load_clip(M.sample_clips()["16_35"], fps=30)
    for order in ("ZYX", "ZXY"):
        out = tmp_path / f"clip_{order}.bvh"
        M.write_bvh(out, motion, order=order)
        back = M.read_bvh(out)
        assert back.skeleton.names == motion.skeleton.names
        np.testing.assert_array_equal(back.skeleton.end_site, motion.skeleton.end_site)
        np.testing.assert_allclose(back.skeleton.offsets_m, motion.skeleton.offsets_m, atol=1e-10)
        assert back.fps == pytest.approx(motion.fps, rel=1e-9)
        dots = np.abs(np.sum(back.rotations * motion.rotations, axis=-1))
        np.testing.assert_allclose(dots, 1.0, atol=1e-9)
        np.testing.assert_allclose(M.forward_kinematics(back)[0], M.forward_kinematics(motion)[0], atol=1e-8)


def test_c3d_markers_in_metres_with_labels_and_rate(shared_mocap):
    data = M.read_c3d(shared_mocap / "markers/ktk_kinematics_tennis_serve.c3d")
    assert data.fps == 50 and data.positions_m.shape == (data.n_frames, len(data.labels), 3)
    assert any("C7" in label for label in data.labels)
    assert 0.5 < np.nanmax(data.positions_m[..., 2]) < 3.5  # metres (mm would be ~2000)
    removed = M.read_c3d(shared_mocap / "markers/clouthier_S01_Pronetokneel01_mksrem.c3d")
    assert np.isnan(removed.positions_m).any()


GOOD_BVH = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Knee
  {
    OFFSET 0 -40 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 -40 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
0 90 0 0 0 0 10 0 0
0 90 0 0 0 0 20 0 0
"""


def test_small_bvh_parses_to_known_pose(tmp_path):
    path = tmp_path / "good.bvh"
    path.write_text(GOOD_BVH)
    motion = M.read_bvh(path, scale="cm")
    pos, _ = M.forward_kinematics(motion)
    np.testing.assert_allclose(pos[0, 0], [0, 0.9, 0])
    c, s = np.cos(np.radians(10)), np.sin(np.radians(10))
    np.testing.assert_allclose(pos[0, 2], [0.4 * s, 0.9 - 0.4 - 0.4 * c, 0], atol=1e-12)  # knee turned about Z


@pytest.mark.parametrize("mutate, line, problem", [
    (lambda t: t.replace("Frames: 2", "Frames: 3"), 20, "header says 3 frames, file holds 2"),
    (lambda t: t.replace("0 90 0 0 0 0 20 0 0", "0 90 0 0 0 0 20 0"), 20, "frame 1 has 8 values, expected 9"),
    (lambda t: t.replace("0 90 0 0 0 0 20 0 0", "0 90 0 0 0 zero 20 0 0"), 20, "frame 1 holds a non-number"),
    (lambda t: t.replace("OFFSET 0 -40 0\n    CHANNELS", "OFFSET 0 -4x0 0\n    CHANNELS"), 8, "bad OFFSET"),
    (lambda t: t.replace("Zrotation Xrotation Yrotation\n    End", "Zrotation Xrotation Wrotation\n    End"), 9, "unknown channel"),
    (lambda t: t.replace("  }\n}\nMOTION", "  }\nMOTION"), 15, "unbalanced braces"),
    (lambda t: t.replace("MOTION\n", ""), None, "no MOTION section"),
    (lambda t: t.replace("HIERARCHY", "HIERARCHIE"), 1, "HIERARCHY"),
])
def test_malformed_bvh_names_file_line_and_problem(tmp_path, mutate, line, problem):
    path = tmp_path / "bad.bvh"
    path.write_text(mutate(GOOD_BVH))
    with pytest.raises(MalformedFileError) as err:
        M.read_bvh(path)
    assert err.value.line == line and problem in err.value.problem
    assert str(path) in str(err.value) and problem in str(err.value)


def _cmu_texts() -> tuple[str, str]:
    clips = M.sample_clips()
    return (clips["16_16"].with_name("16.asf").read_text(), clips["16_45"].read_text())


def _line_of(text: str, needle: str) -> int:
    """1-based number of the first line whose stripped text equals needle."""
    return [line.strip() for line in text.splitlines()].index(needle) + 1


@pytest.mark.parametrize("which, old, new, problem", [
    ("asf", "    dof rx ry rz\n", "    dof rx ry tz\n", "unsupported dof"),
    ("asf", "  angle deg", "  angle grad", "angle unit must be deg or rad"),
    ("asf", "     direction 0.34202 -0.939693 0  \n", "     direction 0.34202 -0.939693\n", "direction: expected 3 numbers"),
    ("asf", "lfemur ltibia", "lfemur lshin", "hierarchy names unknown bone 'lshin'"),
    ("amc", "rtibia 54.2607", "rtibia 54.2607 2", "has 2 values, expected 1"),
    ("amc", "lfemur 19.5251 -5.36343 -30.9686", "lfemur 19.5251 -5.3634e -30.9686", "non-number"),
    ("amc", "lhumerus -27.9576 -13.883 91.1768", "lhumeros -27.9576 -13.883 91.1768", "unknown bone 'lhumeros'"),
])
def test_malformed_asf_amc_names_file_line_and_problem(tmp_path, which, old, new, problem):
    asf_text, amc_text = _cmu_texts()
    text = asf_text if which == "asf" else amc_text
    assert old in text, old
    text = text.replace(old, new, 1)
    asf_path, amc_path = tmp_path / "16.asf", tmp_path / "16_45.amc"
    asf_path.write_text(text if which == "asf" else asf_text)
    amc_path.write_text(text if which == "amc" else amc_text)
    with pytest.raises(MalformedFileError) as err:
        M.load_clip(amc_path)
    bad = asf_path if which == "asf" else amc_path
    assert err.value.path == str(bad) and problem in err.value.problem
    assert err.value.line == _line_of(text, new.strip())


def test_amc_with_a_bone_missing_from_a_frame_is_rejected(tmp_path):
    asf_text, amc_text = _cmu_texts()
    lines = amc_text.splitlines()
    second_frame = lines.index("2")
    drop = next(i for i in range(second_frame, len(lines)) if lines[i].startswith("rtibia"))
    (tmp_path / "16.asf").write_text(asf_text)
    (tmp_path / "16_45.amc").write_text("\n".join(lines[:drop] + lines[drop + 1:]))
    with pytest.raises(MalformedFileError, match="repeated or out of place|missing from frame"):
        M.load_clip(tmp_path / "16_45.amc")


def test_c3d_and_clip_type_errors(tmp_path):
    junk = tmp_path / "junk.c3d"
    junk.write_bytes(b"\x00\x01not a c3d file" * 10)
    with pytest.raises(MalformedFileError, match="junk.c3d"):
        M.read_c3d(junk)
    (tmp_path / "clip.fbx").write_bytes(b"Kaydara FBX Binary")
    with pytest.raises(MalformedFileError, match="unsupported clip type"):
        M.load_clip(tmp_path / "clip.fbx")
    with pytest.raises(MalformedFileError, match="no such file"):
        M.load_clip(tmp_path / "missing.amc")


def _rewrite_amc(text: str, root_perm: list[int] | None, to_radians: bool) -> str:
    """Re-express an AMC: permute the root columns and/or convert every angle to radians."""
    out = []
    for line in text.splitlines():
        fields = line.split()
        if line.strip() == ":DEGREES" and to_radians:
            out.append(":RADIANS")
        elif len(fields) > 1 and not line.startswith((":", "#")):
            vals = np.array(fields[1:], float)
            if fields[0] == "root":
                if to_radians:
                    vals[3:] = np.radians(vals[3:])
                if root_perm is not None:
                    vals = vals[root_perm]
            elif to_radians:
                vals = np.radians(vals)
            out.append(" ".join([fields[0]] + [repr(float(v)) for v in vals]))
        else:
            out.append(line)
    return "\n".join(out) + "\n"


def _rewrite_asf(text: str, to_radians: bool, root_order: str | None, length_factor: float) -> str:
    out = []
    for line in text.splitlines():
        fields = line.split()
        if fields[:1] == ["axis"] and len(fields) == 5 and to_radians:
            angles = np.radians(np.array(fields[1:4], float))
            line = "     axis " + " ".join(repr(float(a)) for a in angles) + " " + fields[4]
        elif fields[:1] == ["angle"] and to_radians:
            line = "  angle rad"
        elif fields[:1] == ["order"] and root_order is not None:
            line = "   order " + root_order
        elif fields[:1] == ["length"] and len(fields) == 2 and fields[1] == "0.45":
            line = f"  length {0.45 * length_factor!r}"
        elif fields[:1] == ["length"] and length_factor != 1.0:
            line = f"     length {float(fields[1]) * length_factor!r}"
        out.append(line)
    return "\n".join(out) + "\n"


def test_asf_amc_units_and_root_order_are_honoured(tmp_path):
    """The same take re-expressed in radians, with another root column order and another length unit
    must give the same joint positions."""
    src = M.sample_clips()["16_45"]
    reference = M.forward_kinematics(M.load_clip(src))[0]
    asf_text, amc_text = src.with_name("16.asf").read_text(), src.read_text()
    perm = [3, 4, 5, 0, 1, 2]  # file columns become RX RY RZ TX TY TZ
    (tmp_path / "16.asf").write_text(_rewrite_asf(asf_text, True, "RX RY RZ TX TY TZ", 2.0))
    amc = _rewrite_amc(amc_text, perm, True)
    # bone lengths doubled with the unit doubled: same metres; the root translation must double too
    lines = []
    for line in amc.splitlines():
        if line.startswith("root "):
            vals = np.array(line.split()[1:], float)
            vals[3:] *= 2.0
            line = "root " + " ".join(repr(float(v)) for v in vals)
        lines.append(line)
    (tmp_path / "16_45.amc").write_text("\n".join(lines) + "\n")
    asf = M.read_asf(tmp_path / "16.asf")
    assert not asf.angle_in_degrees and asf.root_order == ("rx", "ry", "rz", "tx", "ty", "tz")
    np.testing.assert_allclose(M.forward_kinematics(M.load_clip(tmp_path / "16_45.amc"))[0], reference, atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), order=st.sampled_from(["ZYX", "ZXY", "XYZ", "YZX"]),
       gimbal=st.booleans())
def test_bvh_round_trip_holds_for_random_rotations_including_gimbal_lock(tmp_path_factory, seed, order, gimbal):
    rng = np.random.default_rng(seed)
    skel = M.Skeleton(("root", "a", "b", "b_end"), np.array([-1, 0, 1, 2]),
                      rng.normal(scale=0.3, size=(4, 3)), np.array([False, False, False, True]))
    n = 6
    rotations = quat.normalize(rng.normal(size=(n, 4, 4)))
    if gimbal:  # middle Euler angle at +-90 deg: the decomposition is not unique, the rotation must still be
        angles = rng.uniform(-np.pi, np.pi, size=(n, 4, 3))
        angles[..., 1] = np.pi / 2 * rng.choice([-1.0, 1.0], size=(n, 4))
        rotations = quat.from_euler(angles, order)
    rotations[:, 3] = quat.identity((n,))
    motion = M.Motion(skel, 60.0, rng.normal(size=(n, 3)), rotations)
    path = tmp_path_factory.mktemp("rt") / "random.bvh"
    M.write_bvh(path, motion, order=order)
    back = M.read_bvh(path, scale="cm")
    np.testing.assert_allclose(M.forward_kinematics(back)[0], M.forward_kinematics(motion)[0], atol=1e-8)
    np.testing.assert_allclose(np.abs(np.sum(back.rotations * motion.rotations, axis=-1)), 1.0, atol=1e-8)
