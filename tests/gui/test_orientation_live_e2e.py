"""Issue 18 "Live": `courtside gateway --emulate 2 --emulate-orientation` (stations speaking protocol v2, their
sensors' orientation from the realistic magnetometer-free filter error model, gyroscopes from the mocap) on a
non-default loopback address, and `courtside console --connect` as a second process: the console receives the
orientations and angular rates, pushes them with every frame, and says which inputs its engine uses.

Observed through the console's saved-poses meta (the same counters its status bar shows): the frames that carried
orientation and angular rate, and the engine's `EngineSpec.inputs`."""
from __future__ import annotations

import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from engine.stream.poses_file import load_poses
from tests.gateway.court_setup import start_gateway

HOST = "127.0.0.7"
CLIP = "16_01"


@pytest.mark.slow
def test_console_process_receives_and_pushes_orientations(tmp_path):
    from engine.graph.cli import build_graph_main
    from engine.mocap import sample_clips

    clips = sample_clips()
    assert build_graph_main([str(clips["16_11"]), str(clips[CLIP]), "-o", str(tmp_path / "g.npz")]) == 0
    gateway, port = start_gateway(tmp_path, "--emulate", "2", "--emulate-orientation", "--emulate-clip", CLIP,
                                  "--listen", f"{HOST}:0", mode="no authentication: loopback only")
    try:
        env = dict(os.environ, QT_QPA_PLATFORM="offscreen", COURTSIDE_CACHE_DIR=str(tmp_path / "cache"))
        console = subprocess.run([sys.executable, "-m", "gateway.cli", "console", "--connect", f"{HOST}:{port}",
                                  "--graph", "g.npz", "--duration", "12", "--save-poses", "live.npz"],
                                 cwd=tmp_path, capture_output=True, text=True, timeout=400, env=env)
        assert console.returncode == 0, console.stderr[-3000:]
    finally:
        gateway.send_signal(signal.SIGTERM)
        _, err = gateway.communicate(timeout=60)
    assert gateway.returncode == 0 and "Traceback" not in err, err[-2000:]
    meta = load_poses(tmp_path / "live.npz").meta
    assert meta["frames_in"] > 60, meta
    # every frame with its accelerations also carried every sensor's orientation and angular rate
    with_acc = meta["frames_in"] - meta["frames_invalid"]
    assert meta["frames_with_orientation"] == meta["frames_with_gyro"] == with_acc, meta
    # the motion graph's orientation term (camera-following preset) is what the engine says it uses
    assert list(meta["engine_inputs"]) == ["acc", "orientation"], meta
    assert meta["engine_label"].endswith("acc+orientation (tilt only))"), meta  # no calibration record: no yaw


def test_status_bar_names_the_engine_inputs_and_the_streamed_channels():
    from types import SimpleNamespace

    from engine.stream.engines import EngineSpec
    from gui.athlete_status import streamed_summary

    spec = EngineSpec("motion-graph", "g.npz", ("chest",), 30.0, np.zeros(1, int), lambda lag: None,
                      inputs=("acc", "orientation"))
    assert spec.label.endswith("acc+orientation)")  # what the engine uses, in the status bar's engine label
    posed = EngineSpec("motion-graph", "g.npz", ("chest",), 30.0, np.zeros(1, int), lambda lag: None,
                       inputs=("acc", "orientation"), inputs_note="calibrated yaw")
    assert posed.label.endswith("acc+orientation (calibrated yaw))")  # and how: segments posed with their yaw
    assert streamed_summary(SimpleNamespace(frames_with_orientation=10, frames_with_gyro=10)) == \
        "streamed acc+orientation+gyro"
    assert streamed_summary(SimpleNamespace(frames_with_orientation=3, frames_with_gyro=0)) == \
        "streamed acc+orientation"
    assert streamed_summary(SimpleNamespace(frames_with_orientation=0, frames_with_gyro=0)) == "streamed acc"
