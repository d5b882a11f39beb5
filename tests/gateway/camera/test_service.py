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
