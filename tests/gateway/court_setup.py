"""A whole court in a temporary directory for subprocess tests: rendered court video + its calibration written by
`courtside camera calibrate`, secrets, and a `court.toml` with emulated stations replaying mocap, the camera,
the calibration wizard and authentication; plus helpers to run `courtside gateway` on it as a real process.
Used by tests/gateway/test_gateway_config_process.py and the console's two-process end-to-end test."""
from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from engine.mocap import SEED000_SENSORS
from gateway import auth
from gateway.camera.court import COURT_KEYPOINTS_M, keypoints_array
from gateway.camera.synthetic import default_court_camera

SIZE = (480, 270)


def courtside(*args: str, cwd) -> subprocess.CompletedProcess:
    result = subprocess.run([sys.executable, "-m", "gateway.cli", *args], cwd=cwd, capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    return result


def start_gateway(cwd, *args: str, mode: str = "authentication required") -> tuple[subprocess.Popen, int]:
    """`courtside gateway ARGS` as a process; returns it and its port once it says it listens in ``mode``."""
    proc = subprocess.Popen([sys.executable, "-m", "gateway.cli", "gateway", *args], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        assert line, f"gateway exited early ({proc.poll()}): {proc.stderr.read()}"
        if match := re.match(rf"gateway listening on ([0-9.]+):(\d+) \({re.escape(mode)}", line):
            return proc, int(match[2])
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
    assert "Traceback" not in err, err
    return out, err


def wait_for(predicate, timeout_s: float = 30.0):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError("condition not met in time")


def make_court(tmp_path: Path, listen: str = "127.0.0.2:0", record: str = "match",
               clips: tuple[str, ...] = ("16_32", "16_36"), seconds: float = 10.0) -> Path:
    """In ``tmp_path``: a court video rendered from the synthetic camera, its calibration fitted by `courtside
    camera calibrate` from the projected keypoints (as an operator's clicks), operator and viewer secrets, and
    ``court.toml`` naming them all (2 emulated stations replaying ``clips``, the calibration wizard over the
    seed-000 sites, authentication, ``record`` started at once). Returns ``tmp_path``."""
    courtside("camera", "synth", "--out", "court.mp4", "--calibration", "synth_court.json", "--truth", "truth.csv",
              "--seconds", str(seconds), "--fps", "15", "--width", str(SIZE[0]), "--height", str(SIZE[1]), cwd=tmp_path)
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
listen = "{listen}"
record_dir = "takes"
record = "{record}"
log_level = "warning"
status_interval_s = 0.5
clock_lock_after_s = 5

[stations]
emulate = 2
emulate_clips = [{", ".join(f'"{c}"' for c in clips)}]

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
