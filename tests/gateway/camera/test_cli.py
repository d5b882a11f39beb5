"""Camera CLI round trip: render a clip to an mp4, calibrate from clicks, track the file back."""
from __future__ import annotations

import json
import re

import numpy as np

from gateway.camera import COURT_KEYPOINTS_M, CourtCalibration
from gateway.camera.cli import main


def test_synth_then_track_a_video_file(tmp_path, capsys):
    video, calib, truth, out = (tmp_path / n for n in ("c.mp4", "c.json", "t.csv", "r.jsonl"))
    assert main(["synth", "--seconds", "3", "--seed", "2", "--out", str(video), "--calibration", str(calib),
                 "--truth", str(truth)]) == 0
    assert main(["track", "--video", str(video), "--calibration", str(calib), "--truth", str(truth),
                 "--out", str(out)]) == 0
    rms = float(re.search(r"position RMS ([0-9.]+) m", capsys.readouterr().err).group(1))
    assert rms < 0.2  # through a lossy mp4 codec
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(records) > 80 and {"t_host_s", "x_m", "y_m", "heading_rad", "confidence"} <= set(records[0])


def test_calibrate_from_clicks_and_errors(tmp_path, capsys, court_camera):
    names = list(COURT_KEYPOINTS_M)[:8]
    court = np.array([COURT_KEYPOINTS_M[n] for n in names])
    px = court_camera.project(np.column_stack([court, np.zeros(len(court))]))
    clicks = tmp_path / "clicks.json"
    clicks.write_text(json.dumps({n: list(p) for n, p in zip(names, px)}))
    out = tmp_path / "venue.json"
    assert main(["calibrate", "--clicks", str(clicks), "--image-size", "800", "450", "--focal-px", "480",
                 "--out", str(out)]) == 0
    assert json.loads(capsys.readouterr().out)["rms_m"] < 1e-3
    np.testing.assert_allclose(CourtCalibration.load(out).camera_position_m(), court_camera.position_m, atol=0.01)
    assert main(["track", "--video", str(tmp_path / "none.mp4"), "--calibration", str(out)]) == 2
    assert "none.mp4: no such video file" in capsys.readouterr().err


def test_synth_with_an_opponent_and_track_the_chosen_side(tmp_path, capsys):
    video, calib, truth = (tmp_path / n for n in ("c.mp4", "c.json", "t.csv"))
    assert main(["synth", "--seconds", "3", "--seed", "2", "--opponent", "--out", str(video), "--calibration",
                 str(calib), "--truth", str(truth)]) == 0
    capsys.readouterr()
    rms = {}
    for side in ("near", "far"):
        assert main(["track", "--video", str(video), "--calibration", str(calib), "--truth", str(truth),
                     "--side", side, "--out", str(tmp_path / f"{side}.jsonl")]) == 0
        rms[side] = float(re.search(r"position RMS ([0-9.]+) m", capsys.readouterr().err).group(1))
    assert rms["near"] < 0.2  # the instrumented (truth) player
    assert rms["far"] > 5.0  # the opponent on the other half, as asked
