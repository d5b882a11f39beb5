"""The camera track gives each frame the fix for its own time."""
from __future__ import annotations

import numpy as np

from engine.stream import CameraTrack


def test_each_frame_gets_the_fix_interpolated_at_its_own_time():
    cam = CameraTrack(max_gap_s=0.5)
    fixes = np.arange(0, 2.0, 1 / 12)  # 12 fps, a player walking at 1.5 m/s along x, heading across +-pi
    for t in fixes:
        cam.add(t, [1.5 * t, -3.0], np.pi - 0.1 + 0.2 * t)
    frames = np.arange(0, 58) / 30.0  # the last fix is at 23/12 = 1.917 s: frame 57 (1.9 s) is the last inside
    pos, head = cam.at(frames)
    np.testing.assert_allclose(pos, np.c_[1.5 * frames, np.full(len(frames), -3.0)], atol=1e-12)
    expected = (np.pi - 0.1 + 0.2 * frames + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(np.angle(np.exp(1j * (head - expected))), 0, atol=1e-12)  # wrapped the short way


def test_gaps_lost_player_and_times_outside_the_track_give_no_position():
    cam = CameraTrack(max_gap_s=0.5)
    for t, p in [(0.0, [0, 0]), (0.1, [1, 0]), (0.2, None), (0.3, [3, 0]), (1.0, [10, 0]), (1.1, [11, 0])]:
        cam.add(t, p)
    cam.add(0.5, [5, 0])  # out of order: dropped
    pos, head = cam.at(np.array([-0.1, 0.05, 0.15, 0.3, 0.6, 1.05, 1.2]))
    assert np.isnan(pos[0]).all() and np.isnan(pos[-1]).all()  # before / after the track
    np.testing.assert_allclose(pos[1], [0.5, 0])
    assert np.isnan(pos[2]).all()  # next to a fix without a player
    np.testing.assert_allclose(pos[3], [3, 0])  # exactly on a fix: its own value
    assert np.isnan(pos[4]).all()  # 0.7 s between fixes > max gap
    np.testing.assert_allclose(pos[5], [10.5, 0])
    assert np.isnan(head).all()
