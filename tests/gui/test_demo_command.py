"""`courtside demo` end to end in a subprocess: real emulated stations replaying held-out mocap, gateway,
synthetic camera, console — and its screenshot shows both the synthesized and the ground-truth skeleton."""
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
    assert estimate.sum() > 300, estimate.sum()
    assert truth.sum() > 300, truth.sum()
    assert "held-out" in proc.stderr and "demo gateway on" in proc.stderr
