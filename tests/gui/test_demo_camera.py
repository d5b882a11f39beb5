"""The demo's synthetic camera shows the opponent on the other half; one track follows each athlete."""
from __future__ import annotations

import threading
import time

import numpy as np

from gui.demo.hardware import DemoCamera
from gui.demo.performance import OPPONENT, PLAYER, build_opponent, build_performance


def test_demo_camera_tracks_each_athlete_with_its_own_track():
    perf = build_performance()
    cam = DemoCamera(perf, t0_monotonic_s=0.0, duration_s=12.0, opponent=build_opponent())
    assert len(cam.source.opponents) == 1
    err: dict[str, list[float]] = {PLAYER: [], OPPONENT: []}
    opponent_sides = set()
    for frame in cam.source:
        records = cam.tracker.update_all(frame)
        if not frame.truth.visible:
            continue
        opponent = cam.source.opponents[0].state(frame.truth.t_true_s)
        opponent_sides.add(np.sign(opponent.y_m) != np.sign(frame.truth.y_m))
        for name, (x, y) in ((PLAYER, (frame.truth.x_m, frame.truth.y_m)), (OPPONENT, (opponent.x_m, opponent.y_m))):
            if records[name] is not None:
                err[name].append(np.hypot(records[name].x_m - x, records[name].y_m - y))
    for name, e in err.items():
        assert len(e) > 0.9 * 12.0 * 12, name  # 12 fps
        assert np.sqrt(np.mean(np.square(e))) < 0.25, name
    assert opponent_sides == {True}  # the opponent really was on the other half all along


def test_demo_camera_that_falls_behind_the_wall_clock_skips_ahead_instead_of_publishing_old_frames():
    """Started 5 s late (as a renderer on a starved machine ends up), the camera jumps to the present like a real
    camera, rather than publishing 5 s of stale frames that reach the console after their frames were decided."""
    cam = DemoCamera(build_performance(), t0_monotonic_s=time.monotonic() - 5.0, duration_s=12.0)
    published, done = [], threading.Event()

    def sink(obs, jpeg) -> None:
        published.append((obs, time.monotonic()))
        if len(published) >= 3:
            done.set()

    started = time.monotonic()
    cam.start(sink)
    try:
        assert done.wait(60.0), "the camera published nothing"
    finally:
        cam.stop()
    first = published[0][0]
    assert first["t_host_s"] >= started - cam.MAX_LAG_S  # the old code started 7.5 s in the past (empty court)
    assert first["frame_index"] >= 5.0 * 12 and cam.source.dropped >= 5.0 * 12  # the skipped frames count as dropped
    frames = [o["frame_index"] for o, _ in published if o["athlete"] == PLAYER]  # one observation per athlete
    assert frames == sorted(set(frames))
