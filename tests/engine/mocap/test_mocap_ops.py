"""Resampling, heading, foot contacts, roles and clip/database loading."""
import os

import numpy as np
import pytest

import engine.mocap as M
from engine.mocap import quaternions as quat
from tests.engine.mocap.helpers import axis_angle, chain_skeleton


def test_resample_120_to_30_is_every_fourth_frame_of_real_data():
    motion = M.load_clip(M.sample_clips()["16_35"])
    low = M.resample(motion, 30)
    assert low.fps == 30 and low.n_frames == (motion.n_frames - 1) // 4 + 1
    np.testing.assert_allclose(low.root_positions_m, motion.root_positions_m[::4], atol=1e-12)
    dots = np.abs(np.sum(low.rotations * motion.rotations[::4], axis=-1))
    np.testing.assert_allclose(dots, 1.0, atol=1e-12)


def test_resample_to_a_non_integer_ratio_interpolates_exactly_on_uniform_motion():
    n, fps, omega, speed = 121, 120.0, 1.3, np.array([0.5, 0.0, -1.0])
    t = np.arange(n) / fps
    rots = quat.identity((n, 4))
    rots[:, 1] = axis_angle("X", omega * t)  # constant angular velocity: slerp is exact
    motion = M.Motion(chain_skeleton(), fps, t[:, None] * speed, rots)
    out = M.resample(motion, 25.0)
    t_out = np.arange(out.n_frames) / 25.0
    assert out.n_frames == 26 and t_out[-1] == pytest.approx(1.0)
    np.testing.assert_allclose(out.root_positions_m, t_out[:, None] * speed, atol=1e-12)
    dots = np.abs(np.sum(out.rotations[:, 1] * axis_angle("X", omega * t_out), axis=-1))
    np.testing.assert_allclose(dots, 1.0, atol=1e-12)


def test_heading_follows_the_walking_direction_and_a_turned_clip():
    motion = M.load_clip(M.sample_clips()["16_16"], fps=30)
    step = motion.root_positions_m[-1] - motion.root_positions_m[0]
    travel = np.arctan2(step[0], step[2])
    heading = M.root_heading(motion)
    assert abs(M.wrap_angle(np.median(heading) - travel)) < np.radians(15)
    # yaw the whole clip by +60 deg about Y: heading turns by +60 deg (counter-clockwise from above)
    yaw = axis_angle("Y", np.radians(60))
    rotations = motion.rotations.copy()
    rotations[:, 0] = quat.multiply(yaw[None], motion.rotations[:, 0])
    turned = M.Motion(motion.skeleton, motion.fps, quat.rotate(yaw, motion.root_positions_m), rotations)
    np.testing.assert_allclose(M.wrap_angle(M.root_heading(turned) - heading), np.radians(60), atol=1e-9)
    np.testing.assert_allclose(M.ground_positions(turned)[:, 1], turned.root_positions_m[:, 2])


def test_foot_contacts_alternate_on_a_real_walk_and_fly_in_a_run():
    walk = M.load_clip(M.sample_clips()["16_11"], fps=30)
    contacts = M.foot_contacts(walk)
    duty = contacts.mean(axis=0)
    assert np.all((duty > 0.5) & (duty < 0.8))  # walking: each foot down ~60 % of the time
    assert contacts.any(axis=1).all()  # a walk always has a foot down
    double = contacts.all(axis=1).mean()
    assert 0.05 < double < 0.5  # double support phases exist but do not dominate
    # alternation: left-only and right-only stance phases take turns
    single = np.where(contacts[:, 0] & ~contacts[:, 1], 1, np.where(contacts[:, 1] & ~contacts[:, 0], 2, 0))
    phases = single[single > 0]
    changes = phases[np.flatnonzero(np.diff(phases)) + 1]
    assert len(changes) >= 3 and np.all(np.diff(changes) != 0)
    run = M.foot_contacts(M.load_clip(M.sample_clips()["16_35"], fps=30))
    assert 0.2 < (~run.any(axis=1)).mean() < 0.6  # flight phases
    assert run.mean() < 0.45


def test_roles_and_error_joints_on_the_shipped_skeleton():
    skel = M.load_clip(M.sample_clips()["16_45"]).skeleton
    roles = M.joint_roles(skel)
    assert set(roles) == set(M.ROLES) and len(M.ROLES) == 23
    assert skel.names[roles["right_elbow"]] == "rradius" and skel.names[roles["pelvis"]] == "root"
    err = M.error_joint_indices(skel)
    assert len(err) == 21 and len(set(err.tolist())) == 21
    rest = skel.rest_positions()
    assert rest[roles["left_hip"], 0] > 0 > rest[roles["right_hip"], 0]  # left is +X when facing +Z
    with pytest.raises(ValueError, match="no known naming convention"):
        M.joint_roles(chain_skeleton())


def test_sample_clips_and_licence_file():
    clips = M.sample_clips()
    assert {"16_11", "16_16", "16_32", "16_21", "16_35", "16_36", "16_45", "16_01", "16_05", "135_04"} == set(clips)
    readme = (M.DATA_DIR / "README.md").read_text()
    assert "The data used in this project was obtained from mocap.cs.cmu.edu." in readme
    assert "NSF EIA-0196217" in readme
    assert sum(p.stat().st_size for p in M.DATA_DIR.rglob("*")) < 4_000_000


def test_load_database_resamples_and_caches(tmp_path):
    src = M.sample_clips()
    clip = tmp_path / "16_45.amc"
    clip.write_text(src["16_45"].read_text())
    (tmp_path / "16.asf").write_text(src["16_45"].with_name("16.asf").read_text())
    cache = tmp_path / "cache"
    first = M.load_database([clip, src["16_36"]], fps=30, cache_dir=cache)
    assert [m.fps for m in first] == [30, 30] and len(list(cache.glob("*.npz"))) == 2
    again = M.load_database([clip], fps=30, cache_dir=cache)[0]
    np.testing.assert_array_equal(again.rotations, first[0].rotations)
    assert again.skeleton.names == first[0].skeleton.names and again.name == "16_45"
    # editing the source invalidates its entry (key includes size and mtime)
    lines = clip.read_text().splitlines()
    cut = lines.index("100")
    clip.write_text("\n".join(lines[:cut]) + "\n")
    os.utime(clip, ns=(1, 1))
    shorter = M.load_database([clip], fps=30, cache_dir=cache)[0]
    assert shorter.n_frames < again.n_frames and len(list(cache.glob("*.npz"))) == 3
