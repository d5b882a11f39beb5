"""Tracking real human motion: shipped CMU clips rendered as the player, scored against their root trajectory."""
from __future__ import annotations

import numpy as np
import pytest

from engine.mocap import load_clip, sample_clips
from gateway.camera import CameraImperfections, PlayerTracker, SyntheticCourtCamera
from gateway.camera.mocap_body import MocapBody


@pytest.mark.parametrize(("clip", "centre"), [("16_05", (2.0, -9.0)), ("16_21", (-3.0, -6.0)), ("16_45", (0.0, -10.0))])
def test_mocap_clip_position_rms(court_camera, calibration, clip, centre):
    """Forward jump, fast walk and a 4 m/s run, placed at different spots of the near half."""
    body = MocapBody(load_clip(sample_clips()[clip], fps=30.0), centre)
    source = SyntheticCourtCamera(body.path, camera=court_camera, body=body, seed=5,
                                  imperfections=CameraImperfections(drop_probability=0.03, jitter_s=0.002))
    tracker = PlayerTracker(calibration)
    pairs = [(r, f.truth) for f in source if (r := tracker.update(f)) is not None and f.truth.visible]
    assert len(pairs) >= 0.9 * body.path.duration_s * 30 * 0.97 - 2
    err = np.array([[r.x_m - t.x_m, r.y_m - t.y_m] for r, t in pairs])
    rms = float(np.sqrt(np.mean(np.sum(err**2, axis=1))))
    print(f"{clip}: position RMS {rms:.3f} m over {len(pairs)} frames")
    assert rms <= 0.2
    if clip == "16_45":  # running: heading is the direction of motion, close to the hips' heading
        running = [(r, t) for r, t in pairs[10:] if np.hypot(r.vx_mps, r.vy_mps) > 2.0]
        assert len(running) > 10
        heading_err = [abs(np.angle(np.exp(1j * (r.heading_rad - t.heading_rad)))) for r, t in running]
        assert np.degrees(np.median(heading_err)) < 15.0
