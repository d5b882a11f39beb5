"""Chained takes: the root is continuous across seams (exact), each clip's motion is kept rigidly."""
from __future__ import annotations

import numpy as np
import pytest

from engine.errors import CourtsideError
from engine.evaluation.simulate import CameraModel, accelerometers, camera_track
from engine.evaluation.takes import chain_clips, plan_chained_takes
from engine.graph.poses import root_local
from engine.mocap import forward_kinematics, root_heading, virtual_accelerometers, standard_placements, wrap_angle


def test_each_clip_starts_where_the_previous_one_ended(motions):
    ids = [3, 0, 5, 1]
    take = chain_clips(motions, ids, [m.name for m in motions], start_ground_m=np.array([2.0, -1.0]),
                       start_heading_rad=0.7)
    assert take.n_frames == sum(motions[i].n_frames for i in ids)
    assert np.allclose(take.ground_m[0], [2.0, -1.0], atol=1e-12) and take.heading_rad[0] == pytest.approx(0.7)
    for prev, seg in zip(take.segments, take.segments[1:]):
        assert prev.stop == seg.start
        assert np.allclose(take.ground_m[seg.start], take.ground_m[prev.stop - 1], atol=1e-12)
        assert abs(wrap_angle(take.heading_rad[seg.start] - take.heading_rad[prev.stop - 1])) < 1e-9
    for seg in take.segments:  # the placement is rigid: every pose, seen from its own root, is the clip's
        pos, _ = forward_kinematics(motions[seg.clip])
        ours = take.joints_m[seg.start:seg.stop]
        assert np.allclose(root_local(ours, ours[:, 0, [0, 2]], take.heading_rad[seg.start:seg.stop]),
                           root_local(pos, pos[:, 0, [0, 2]], root_heading(motions[seg.clip], pos)), atol=1e-9)
        assert np.allclose(ours[:, :, 1], pos[:, :, 1], atol=1e-12)  # heights untouched


def test_sensors_are_simulated_per_clip_with_no_seam_spike(motions):
    take = chain_clips(motions, [0, 2], [m.name for m in motions])
    acc, times = accelerometers(take, ("right_forearm",), None, np.random.default_rng(0))
    seg = take.segments[1]
    alone = virtual_accelerometers(seg.motion, standard_placements(seg.motion.skeleton, ("right_forearm",)))
    assert np.allclose(acc[seg.start:], alone)
    assert np.allclose(times, np.arange(take.n_frames) / take.fps)


def test_camera_fixes_at_its_rate_with_the_configured_noise(motions):
    take = chain_clips(motions, [0, 1, 2, 3], [m.name for m in motions])
    cam = camera_track(take, CameraModel(0.05, np.radians(10), 10.0), np.random.default_rng(1))
    fixes = np.flatnonzero(np.isfinite(cam.heading_rad))
    assert np.array_equal(fixes, np.arange(0, take.n_frames, 3))
    err = cam.position_m[fixes] - take.ground_m[fixes]
    assert err.std() == pytest.approx(0.05, rel=0.25)
    pos, head = cam.filled()
    assert np.array_equal(pos[4], cam.position_m[3]) and head[5] == cam.heading_rad[3]


def test_plan_changes_content_between_clips_and_never_reuses_a_clip():
    labels = ["walk"] * 6 + ["run"] * 3 + ["kick"] * 2 + ["bow"] * 4
    durations = [5.0] * len(labels)
    takes = plan_chained_takes(labels, durations, n_takes=2, min_duration_s=20.0, seed=3, first="walk")
    used = [c for t in takes for c in t]
    assert len(used) == len(set(used)) == 8
    for t in takes:
        assert labels[t[0]] == "walk" and sum(durations[c] for c in t) >= 20.0
        assert all(labels[a] != labels[b] for a, b in zip(t, t[1:]))
    with pytest.raises(CourtsideError, match="not enough held-out clips"):
        plan_chained_takes(labels, durations, n_takes=4, min_duration_s=30.0)
