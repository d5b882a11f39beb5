"""The demo's synthetic camera shows an opponent on the other half; its tracker follows the performer."""
from __future__ import annotations

import numpy as np

from gui.demo.hardware import DemoCamera
from gui.demo.performance import build_performance


def test_demo_camera_tracks_the_performer_not_the_opponent():
    perf = build_performance()
    cam = DemoCamera(perf, t0_monotonic_s=0.0, duration_s=12.0)
    assert len(cam.source.opponents) == 1
    err, opponent_sides = [], set()
    for frame in cam.source:
        record = cam.tracker.update(frame)
        if record is not None and frame.truth.visible:
            err.append(np.hypot(record.x_m - frame.truth.x_m, record.y_m - frame.truth.y_m))
            opponent = cam.source.opponents[0].state(frame.truth.t_true_s)
            opponent_sides.add(np.sign(opponent.y_m) != np.sign(frame.truth.y_m))
    assert len(err) > 0.9 * 12.0 * 12  # 12 fps
    assert np.sqrt(np.mean(np.square(err))) < 0.25
    assert opponent_sides == {True}  # the opponent really was on the other half all along
