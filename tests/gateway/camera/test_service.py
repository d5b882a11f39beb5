"""Camera hook end to end: synthetic camera paced in real time -> tracker -> gateway -> real TCP client."""
from __future__ import annotations

import time

import cv2
import numpy as np

from gateway.camera import PlayerTracker, SyntheticCourtCamera, scripted_rally_path
from gateway.camera.service import CameraService
from gateway.client import GatewayClient
from gateway.daemon import Gateway


def test_camera_observations_reach_a_client(tmp_path, court_camera, calibration):
    path = scripted_rally_path(2.5, seed=9)
    source = SyntheticCourtCamera(path, camera=court_camera, empty_s=1.0, seed=4)
    service = CameraService(source, PlayerTracker(calibration), realtime=True, thumbnail_every=10)
    got = []
    with Gateway([], listen=("127.0.0.1", 0), record_dir=tmp_path, camera=service) as gw, \
            GatewayClient(*gw.address).connect() as client:
        client.add_listener("camera", got.append)
        deadline = time.monotonic() + 10.0
        while service.running and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.2)
    assert not service.running and service.frames == int(3.5 * 30) + 1
    tracked = [m for m in got if m["tracking"]]
    assert len(tracked) > 0.8 * 2.5 * 30 * 0.8
    t_host = np.array([m["t_host_s"] for m in got])
    assert np.all(np.diff(t_host) > 0)
    assert abs((t_host[-1] - t_host[0]) - (got[-1]["frame_index"] - got[0]["frame_index"]) / 30.0) < 1e-6
    errors = []
    for m in tracked:
        truth = path.state(-1.0 + m["frame_index"] / 30.0)
        errors.append(np.hypot(m["position_m"][0] - truth.x_m, m["position_m"][1] - truth.y_m))
    assert np.sqrt(np.mean(np.square(errors))) < 0.2
    thumbs = [m.arrays["jpeg"] for m in got if "jpeg" in m.arrays]
    assert thumbs and all(m["frame_index"] % 10 == 0 for m in got if "jpeg" in m.arrays)
    image = cv2.imdecode(np.asarray(thumbs[0]), cv2.IMREAD_COLOR)
    assert image.shape[1] == 320


def test_synthetic_factory_streams_tracked_positions():
    got = []
    service = CameraService.synthetic(2.0, seed=1, thumbnail_every=0)
    service.start(lambda obs, jpeg: got.append((obs, jpeg)))
    deadline = time.monotonic() + 10.0
    while service.running and time.monotonic() < deadline:
        time.sleep(0.05)
    service.stop()
    tracked = [obs for obs, _ in got if obs["tracking"]]
    assert len(got) == int(3.0 * 30) + 1 and len(tracked) > 40
    assert all(jpeg is None for _, jpeg in got)
    assert all(abs(obs["t_host_s"] - time.monotonic()) < 15 for obs in tracked)  # on the monotonic clock


def test_overlay_geometry_is_in_thumbnail_pixels(court_camera, calibration):
    """court_to_image and bbox_px must land on the player in the 320 px thumbnail the console draws."""
    path = scripted_rally_path(1.5, seed=2)
    service = CameraService(SyntheticCourtCamera(path, camera=court_camera, empty_s=1.0, seed=5),
                            PlayerTracker(calibration), thumbnail_every=1)
    got = []
    service.start(lambda obs, jpeg: got.append((obs, jpeg)))
    deadline = time.monotonic() + 10.0
    while service.running and time.monotonic() < deadline:
        time.sleep(0.05)
    service.stop()
    obs, jpeg = next((o, j) for o, j in reversed(got) if o["tracking"])
    thumb = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
    h = np.asarray(obs["court_to_image"])
    truth = path.state(-1.0 + obs["frame_index"] / 30.0)
    feet = h @ [truth.x_m, truth.y_m, 1.0]
    fx, fy = feet[:2] / feet[2]
    x0, y0, x1, y1 = obs["bbox_px"]
    assert x0 - 2 <= fx <= x1 + 2 and y0 - 2 <= fy <= y1 + 2  # the player's feet are inside the box
    assert 0 < x0 < x1 <= thumb.shape[1] and 0 < y0 < y1 <= thumb.shape[0]
    corner = h @ [-5.485, -11.885, 1.0]
    full = court_camera.project(np.array([[-5.485, -11.885, 0.0]]))[0]
    np.testing.assert_allclose(corner[:2] / corner[2], full * 320 / 800, atol=0.5)
