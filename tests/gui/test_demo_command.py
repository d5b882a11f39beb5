"""`courtside demo` end to end in a subprocess: real emulated stations replaying held-out mocap, gateway,
synthetic camera, console — and its screenshot shows the synthesized skeletons of both athletes and the ground
truth of the first."""
from __future__ import annotations

import os
import subprocess
import sys

import cv2
import pytest

pytestmark = pytest.mark.slow


def test_demo_runs_for_its_duration_and_shows_two_skeletons(tmp_path):
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", COURTSIDE_CACHE_DIR=str(tmp_path / "cache"))
    proc = subprocess.run([sys.executable, "-m", "gateway.cli", "demo", "--duration", "11", "--screenshots",
                           str(tmp_path / "shots"), "--record-dir", str(tmp_path / "rec")],
                          capture_output=True, text=True, timeout=120, env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    main = cv2.imread(str(tmp_path / "shots" / "main.png"))
    assert main is not None and (tmp_path / "shots" / "devices.png").is_file()
    b, g, r = (main[..., k].astype(int) for k in range(3))
    h, w = r.shape
    view = (slice(int(0.06 * h), int(0.5 * h)), slice(0, int(0.58 * w)))  # the 3-D pane, top left
    estimate = ((r > 100) & (b < 80) & (r - g > 30))[view]
    truth = ((g > 100) & (b > 100) & (r < 90))[view]
    opponent = ((g > 150) & (r < 130) & (b < 130))[view]  # the second athlete's skeleton (green)
    assert estimate.sum() > 300, estimate.sum()
    assert truth.sum() > 300, truth.sum()
    assert opponent.sum() > 300, opponent.sum()
    assert "held-out" in proc.stderr and "demo gateway on" in proc.stderr


def _demo(tmp_path, *args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", COURTSIDE_CACHE_DIR=str(tmp_path / "cache"))
    return subprocess.run([sys.executable, "-m", "gateway.cli", "demo", "--duration", "5", "--no-camera",
                           "--record-dir", str(tmp_path / "rec"), *args],
                          capture_output=True, text=True, timeout=120, env=env, cwd=tmp_path)


def _one_line_error(proc: subprocess.CompletedProcess) -> str:
    errors = [line for line in proc.stderr.splitlines() if not line.startswith("INFO ")]
    assert proc.returncode == 2 and "Traceback" not in proc.stderr and len(errors) == 1, proc.stderr[-3000:]
    return errors[0]


@pytest.mark.parametrize("listen", ["0.0.0.0:0", "192.0.2.1:7766"])
def test_demo_refuses_to_listen_beyond_loopback_in_one_line(tmp_path, listen):
    """The demo gateway has no secret: beyond loopback is refused before anything starts (it used to print two
    tracebacks, one from the hardware process and a RuntimeError from the console)."""
    line = _one_line_error(_demo(tmp_path, "--listen", listen))
    assert line.startswith("courtside demo: --listen ") and "loopback only" in line and "[auth]" in line
    assert not (tmp_path / "rec").exists()


@pytest.mark.parametrize("mode", [[], ["--single-process"]])
def test_demo_on_an_address_in_use_says_so_in_one_line(tmp_path, mode):
    import socket

    with socket.create_server(("127.0.0.5", 0)) as taken:
        port = taken.getsockname()[1]
        line = _one_line_error(_demo(tmp_path, "--listen", f"127.0.0.5:{port}", *mode))
    assert line.startswith(f"courtside demo: the demo gateway cannot start on 127.0.0.5:{port}: Address already in use")
