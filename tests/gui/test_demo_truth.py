"""A take recorded during the demo carries its ground truth, so a console that plays it back later (no demo
running) draws the true skeleton at the right frames."""
from __future__ import annotations

import time

import numpy as np

from gateway.client import GatewayClient
from gui.demo import HELD_OUT_CLIPS, truth_from_events
from gui.demo.hardware import demo_hardware
from gui.main_window import ConsoleWindow


def test_demo_take_plays_back_with_ground_truth(qtbot, tmp_path):
    with demo_hardware(("127.0.0.1", 0), tmp_path, camera=False, duration_s=30) as (address, t0):
        with GatewayClient(*address).connect() as client:
            deadline = time.monotonic() + 60  # waits poll: a generous deadline costs nothing when all is well
            while not all(s["link"] == "streaming" for s in client.list_stations()) and time.monotonic() < deadline:
                time.sleep(0.1)
            client.request("start_recording", take="truth-take", timeout_s=60.0)
            time.sleep(2.5)
            state = client.request("stop_recording", timeout_s=60.0)
    window = ConsoleWindow(None, truth_for_take=truth_from_events)  # the demo's hook: the window knows no demo
    qtbot.addWidget(window)
    try:
        window.load_playback(state["files"][0])
        assert window.truth is not None and window.truth.perf.clip_names == HELD_OUT_CLIPS
        assert window.truth.t0 == t0
        window.seek_playback(2.0)
        window.tick()
        latest = window.store.latest_time()
        assert latest is not None and window.skeleton.truth_m is not None
        np.testing.assert_allclose(window.skeleton.truth_m, window.truth.perf.pose_at(latest - t0))
        assert window.skeleton.parents is not None and len(window.skeleton.parents) == len(window.skeleton.truth_m)
    finally:
        window.shutdown()


def test_the_production_window_imports_no_demo_code():
    """Issue 13 "Shape": `courtside console` must not load the demo (it is handed a truth hook instead)."""
    import subprocess
    import sys

    code = ("import sys, gui.main_window, gui.cli, gui.synthesis, gui.engine_link\n"
            "demo = sorted(m for m in sys.modules if m.startswith('gui.demo'))\n"
            "assert not demo, demo\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
