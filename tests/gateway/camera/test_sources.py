"""Frame sources: synthetic camera timing/ground truth and a real video file read back through OpenCV."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from gateway.camera import (
    CameraImperfections, FrameSourceError, PlayerPath, SyntheticCourtCamera, VideoFileSource, scripted_rally_path,
)


def _still_path(duration_s: float = 1.0, xy=(2.0, -8.0)) -> PlayerPath:
    t = np.linspace(0.0, duration_s, 50)
    return PlayerPath(t, np.tile(xy, (len(t), 1)), np.zeros(len(t)), np.zeros(len(t)))


def test_synthetic_timestamps_drops_and_empty_court(court_camera):
    imp = CameraImperfections(drop_probability=0.2, jitter_s=0.003, latency_s=0.05)
    src = SyntheticCourtCamera(scripted_rally_path(3.0, seed=2), camera=court_camera, fps=30.0, empty_s=0.5,
                               imperfections=imp, seed=1)
    frames = list(src)
    produced = int(np.floor(3.5 * 30)) + 1
    assert len(frames) + src.dropped == produced
    assert 0.1 < src.dropped / produced < 0.3
    indices = np.array([f.index for f in frames])
    assert np.all(np.diff(indices) >= 1) and np.any(np.diff(indices) > 1)  # drops leave gaps
    t_true = np.array([f.truth.t_true_s for f in frames])
    np.testing.assert_allclose(t_true, -0.5 + indices / 30.0)
    err = np.array([f.t_host_s for f in frames]) - t_true
    assert err.mean() == pytest.approx(0.05, abs=0.001)
    assert err.std() == pytest.approx(0.003, rel=0.3)
    visible = np.array([f.truth.visible for f in frames])
    np.testing.assert_array_equal(visible, t_true >= 0.0)


def test_synthetic_player_is_drawn_where_the_truth_says(court_camera):
    """The rendered image differs from the empty court exactly around the projected player position."""
    frames = list(SyntheticCourtCamera(_still_path(), camera=court_camera, empty_s=0.2,
                                       imperfections=CameraImperfections(sensor_noise_dn=0, flicker=0, drift=0)))
    empty, full = frames[0].image.astype(int), frames[-1].image.astype(int)
    changed = np.argwhere(np.abs(full - empty).sum(axis=2) > 40)[:, ::-1]  # (x, y)
    feet_px = court_camera.project(np.array([[2.0, -8.0, 0.0]]))[0]
    head_px = court_camera.project(np.array([[2.0, -8.0, 1.8]]))[0]
    span = np.linalg.norm(head_px - feet_px)
    assert len(changed) > 100
    assert np.linalg.norm(changed.mean(axis=0) - (feet_px + head_px) / 2) < span
    assert np.all(np.linalg.norm(changed - feet_px, axis=1) < 2 * span)


def test_video_file_source_reads_frames_and_container_timestamps(tmp_path, court_camera):
    path = tmp_path / "clip.mp4"
    src = SyntheticCourtCamera(_still_path(0.5), camera=court_camera, fps=25.0, empty_s=0.0)
    written = []
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, court_camera.image_size)
    for frame in src:
        writer.write(frame.image)
        written.append(frame.image)
    writer.release()
    with VideoFileSource(path, t0_host_s=100.0) as video:
        assert video.image_size == court_camera.image_size
        assert video.nominal_fps == pytest.approx(25.0)
        frames = list(video)
    assert len(frames) == len(written)
    np.testing.assert_allclose([f.t_host_s for f in frames], 100.0 + np.arange(len(frames)) / 25.0, atol=1e-6)
    # lossy codec, but the content is the same picture
    assert np.mean(np.abs(frames[3].image.astype(int) - written[3].astype(int))) < 4.0


def test_video_file_source_errors_name_the_file(tmp_path):
    with pytest.raises(FrameSourceError, match="missing.mp4: no such video file"):
        VideoFileSource(tmp_path / "missing.mp4")
    junk = tmp_path / "junk.mp4"
    junk.write_bytes(b"this is not a video" * 10)
    with pytest.raises(FrameSourceError, match="junk.mp4: OpenCV cannot open"):
        VideoFileSource(junk)


def test_opencv_camera_on_a_file_path_and_a_missing_device(tmp_path, court_camera):
    """The live-camera class is thin; without hardware, drive it with a video file path (same grab/retrieve
    path) and check its host-clock timestamps, latency correction and the error for a missing device."""
    import time

    from gateway.camera import OpenCVCamera

    path = tmp_path / "clip.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, court_camera.image_size)
    for frame in SyntheticCourtCamera(_still_path(0.4), camera=court_camera, fps=25.0, empty_s=0.0):
        writer.write(frame.image)
    writer.release()
    before = time.monotonic()
    with OpenCVCamera(str(path), latency_s=0.5) as cam:
        frames = list(cam)
    after = time.monotonic()
    assert len(frames) == 11 and [f.index for f in frames] == list(range(11))
    t = np.array([f.t_host_s for f in frames])
    assert np.all(np.diff(t) >= 0) and before - 0.5 <= t[0] and t[-1] <= after - 0.5
    assert frames[0].image.shape == (court_camera.image_size[1], court_camera.image_size[0], 3)
    with pytest.raises(FrameSourceError, match="camera 97: cannot open"):
        OpenCVCamera(97)
