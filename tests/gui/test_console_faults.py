"""The console under faults (issue 30): a synthesis child killed outright is reaped and restarted, the skeleton
moves again within 3 s, and the athlete's own status block says what happened, not the dead child's figures."""
from __future__ import annotations

import os
import signal
import time
from pathlib import Path

from firmware_protocol.emulator.motion import StillSource
from gateway.client import GatewayClient

RESTART_DEADLINE_S = 3.0


def test_a_killed_synthesis_child_is_restarted_and_the_athlete_status_says_so(live_gateway, qtbot):
    from engine.stream.registry import adapter
    from gui.engine_link import synthesis_setup
    from gui.main_window import ConsoleWindow

    gateway, _ = live_gateway(StillSource(6), 6)
    spec = adapter("motion-graph").shipped_spec()
    with GatewayClient(*gateway.address).connect() as client:
        window = ConsoleWindow(client, synthesis=synthesis_setup(spec, [("st1", i) for i in range(6)]),
                               athlete="player")
        qtbot.addWidget(window)
        window.resize(1200, 800)
        window.show()
        try:
            pacer = window._pacers[""]
            qtbot.waitUntil(lambda: pacer.current is not None and "confidence" in window.athlete_status.text("player"),
                            timeout=30_000)
            assert not window.athlete_status.is_fault_shown("player")
            dead = window.worker.pid
            last_shown = pacer.current
            os.kill(dead, signal.SIGKILL)
            killed = time.monotonic()
            # the view shows a pose of the new child: a later frame than the last one shown before the kill
            qtbot.waitUntil(lambda: window.worker.pid != dead and pacer.current is not None
                            and pacer.current.t_s > last_shown.t_s, timeout=int(RESTART_DEADLINE_S * 1000))
            assert time.monotonic() - killed < RESTART_DEADLINE_S
            assert not Path(f"/proc/{dead}").exists()  # reaped: no zombie left
            window.tick()
            text = window.athlete_status.text("player")
            assert "synthesis restarted after crash (1/3): killed by signal 9" in text
            assert window.athlete_status.is_fault_shown("player")
            window.check_link()  # the alarm bar's once-a-second look: a banner too
            assert "synthesis restarted after crash (1/3)" in window.alarms.active()["synthesis:player"]
        finally:
            window.shutdown()


def test_a_dead_synthesis_shows_no_frame_rate_or_confidence():
    """While no child runs (given up), the status says so instead of the last "30 frames/s, confidence 1.00"."""
    from types import SimpleNamespace

    from engine.stream.registry import adapter
    from gui.athlete_status import athlete_status
    from gui.synthesis import SynthesisStats
    from engine.stream import FramePose

    spec = adapter("motion-graph").shipped_spec()
    stats = SynthesisStats(lag_s=0.5, frames_per_s=30.0, push_ms=3.0)
    pose = FramePose(1, 1 / 30, None, confidence=1.0)
    alive = SimpleNamespace(stats=stats, setup=SimpleNamespace(engine=spec), fault="", is_alive=lambda: True,
                            latest_pose=lambda: pose)
    shown = athlete_status("player", alive)
    assert "30 frames/s" in shown.summary and "confidence 1.00" in shown.summary and shown.faults == ()
    dead = SimpleNamespace(**{**vars(alive), "fault": "synthesis stopped: ...", "is_alive": lambda: False})
    shown = athlete_status("player", dead)
    assert "frames/s" not in shown.summary and "confidence" not in shown.summary
    assert "not running" in shown.summary and shown.faults == ("synthesis stopped: ...",)
