"""`courtside gateway --config court.toml` as a real process on 127.0.0.2 with everything a court has: emulated
stations replaying mocap on ptys, the camera reading a rendered court video whose calibration the court
calibration CLI wrote, the calibration wizard, authentication with operator and viewer secrets, a recording that
continues into a suffixed take after a restart (issue 13)."""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from engine.mocap import SEED000_SENSORS
from gateway import auth
from gateway.camera.court import COURT_KEYPOINTS_M, keypoints_array
from gateway.camera.synthetic import default_court_camera
from gateway.client import GatewayClient, GatewayRequestError
from gateway.recorder import load_take

SIZE = (480, 270)


def courtside(*args: str, cwd) -> subprocess.CompletedProcess:
    result = subprocess.run([sys.executable, "-m", "gateway.cli", *args], cwd=cwd, capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    return result


def start_gateway(cwd, *args: str) -> tuple[subprocess.Popen, int]:
    proc = subprocess.Popen([sys.executable, "-m", "gateway.cli", "gateway", *args], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        assert line, f"gateway exited early ({proc.poll()}): {proc.stderr.read()}"
        if match := re.match(r"gateway listening on 127\.0\.0\.2:(\d+) \(authentication required", line):
            return proc, int(match[1])
    proc.kill()
    raise AssertionError("gateway did not start")


def stop_gateway(proc: subprocess.Popen) -> tuple[str, str]:
    proc.send_signal(signal.SIGTERM)
    try:
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert "Traceback" not in err
    return out, err


def wait_for(predicate, timeout_s: float = 30.0):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError("condition not met in time")


@pytest.fixture()
def court_dir(tmp_path):
    """A court video rendered from the synthetic camera, its calibration fitted by `courtside camera calibrate`
    from the projected keypoints (as an operator's clicks), secrets, and the config naming them all."""
    courtside("camera", "synth", "--out", "court.mp4", "--calibration", "synth_court.json", "--truth", "truth.csv",
              "--seconds", "10", "--fps", "15", "--width", str(SIZE[0]), "--height", str(SIZE[1]), cwd=tmp_path)
    camera = default_court_camera(SIZE)
    names = list(COURT_KEYPOINTS_M)
    clicks = camera.project(np.column_stack([keypoints_array(names), np.zeros(len(names))]))
    (tmp_path / "clicks.json").write_text(json.dumps({n: c.tolist() for n, c in zip(names, clicks)}))
    courtside("camera", "calibrate", "--clicks", "clicks.json", "--image-size", *map(str, SIZE),
              "--focal-px", str(camera.camera_matrix[0, 0]), "--out", "court.json", cwd=tmp_path)
    for name in ("operator.secret", "viewer.secret"):
        auth.write_secret_file(tmp_path / name)
    placements = ", ".join(f'"{s}"' for s in SEED000_SENSORS)
    (tmp_path / "court.toml").write_text(f"""
listen = "127.0.0.2:0"
record_dir = "takes"
record = "match"
log_level = "warning"
status_interval_s = 0.5
clock_lock_after_s = 5

[stations]
emulate = 2
emulate_clips = ["16_32", "16_36"]

[camera]
source = "court.mp4"
court = "court.json"
player_side = "near"
thumbnail_every = 5

[calibration]
placements = [{placements}]
records_dir = "calibrations"

[auth]
operator_secret_file = "operator.secret"
viewer_secret_file = "viewer.secret"
""")
    return tmp_path


def test_gateway_config_runs_a_whole_court(court_dir):
    operator_secret = auth.read_secret_file(court_dir / "operator.secret")
    viewer_secret = auth.read_secret_file(court_dir / "viewer.secret")
    proc, port = start_gateway(court_dir, "--config", "court.toml")
    try:
        with GatewayClient("127.0.0.2", port, secret=operator_secret) as op, \
                GatewayClient("127.0.0.2", port, secret=viewer_secret) as viewer:
            assert op.role == "operator" and viewer.role == "viewer"
            # stations replay mocap: the worn sensors move (not the flat lines of issue 13)
            status = wait_for(lambda: (s := op.status()) and len(s["stations"]) == 2 and all(
                st["link"] == "streaming" for st in s["stations"]) and s)
            assert sorted(len(st["sensors"]) for st in status["stations"]) == [5, 6]
            samples = []
            op.add_listener("samples", lambda m: samples.append(m) if m["station"] == "st1" else None)
            time.sleep(2.0)
            acc = np.concatenate([m["acc_g"] for m in samples if m["sensor"] == 0])
            assert len(acc) > 100 and np.linalg.norm(acc, axis=1).std() > 0.1
            # the camera runs in the gateway: health in status, tracked observations streamed to clients
            camera = wait_for(lambda: (c := viewer.status()["camera"]) and c["tracked"] > 10 and c)
            assert camera["state"] == "running" and camera["fps"] > 5 and camera["source"].endswith("court.mp4")
            observation = viewer.get(timeout_s=5.0, kinds=["camera"])
            assert observation is not None and "t_host_s" in observation.header
            # calibration is attached: the operator assigns, the viewer may only look
            for i, site in enumerate(SEED000_SENSORS):
                op.calibration("assign", sensor=f"st1/{i}", segment=site)
            state = viewer.calibration("state")
            assert {s["segment"] for s in state["sensors"].values() if s.get("segment")} == set(SEED000_SENSORS)
            with pytest.raises(GatewayRequestError, match="needs the operator role"):
                viewer.calibration("reset")
            with pytest.raises(GatewayRequestError, match="not a path"):
                op.calibration("save", path=str(court_dir / "court.toml"))
            # recording started from the config; only the operator may stop it
            with pytest.raises(GatewayRequestError, match="needs the operator role"):
                viewer.stop_recording()
            with pytest.raises(auth.AuthenticationError):
                GatewayClient("127.0.0.2", port).connect()
            final = op.stop_recording()
            assert final["take"] == "match" and final["samples_written"] > 500
    finally:
        out, err = stop_gateway(proc)
    assert re.search(r"camera running\s+\d+\.\d fps .* tracking, confidence", out), out
    take = load_take(court_dir / "takes" / "match")
    assert take.problem is None and {k[0] for k in take.samples} == {"st1", "st2"}
    assert sum(m.kind == "camera" and "position_m" in m.header for m in take.others) > 10

    # restarted by a service manager with the same --record: a new take, not a refusal or a traceback
    proc, port = start_gateway(court_dir, "--config", "court.toml", "--camera-loop")
    try:
        with GatewayClient("127.0.0.2", port, secret=operator_secret) as op:
            assert op.status()["recording"]["take"] == "match-2"
    finally:
        out, _ = stop_gateway(proc)
    assert sorted(p.name for p in (court_dir / "takes").iterdir()) == ["match", "match-2"]
    assert not os.path.exists(court_dir / "calibrations")  # nothing saved, nothing written
