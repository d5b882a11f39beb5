"""Recording from the console and playing the take back through the same views (real gateway, real files)."""
from __future__ import annotations

import numpy as np

from firmware_protocol.emulator.motion import TraceSource
from gateway.client import GatewayClient
from gui.main_window import ConsoleWindow
from gui.widgets.recording import missing_required

FPS = 100.0


def ramp_subject(n_sensors: int, period_s: float = 4.0) -> TraceSource:
    """Sensor k's x reading is a known sawtooth (k + t/period) so played-back values can be checked."""
    t = np.arange(int(period_s * FPS)) / FPS
    acc = np.zeros((len(t), n_sensors, 3))
    acc[..., 0] = np.arange(n_sensors)[None, :] + (t / period_s)[:, None]
    acc[..., 1] = 1.0
    return TraceSource(acc, FPS)


def test_required_sensor_gate_refuses_and_names_missing():
    status = {"t_host_s": 10.0, "stations": [{"station": "st1", "link": "streaming",
                                              "sensors": [{"sensor": 0, "last_t_host_s": 9.9},
                                                          {"sensor": 1, "last_t_host_s": 7.0}]}]}
    assert missing_required(status, [("st1", 0), ("st1", 1), ("st2", 0)]) == [("st1", 1), ("st2", 0)]
    assert missing_required(None, [("st1", 0)]) == [("st1", 0)]
    assert missing_required(status, []) == []


def test_record_then_play_back_through_the_same_views(live_gateway, qtbot, tmp_path):
    gateway, _ = live_gateway(ramp_subject(2), 2)
    client = GatewayClient(*gateway.address).connect()
    window = ConsoleWindow(client, sensor_segments={("st1", 0): "chest", ("st1", 1): "pelvis"})
    qtbot.addWidget(window)
    window.resize(1100, 750)
    window.show()
    try:
        window.tabs.setCurrentIndex(2)
        qtbot.waitUntil(lambda: window.recording.status is not None and not missing_required(
            window.recording.status, window.recording.required), timeout=10_000)
        # the gate names a required sensor that is not streaming, and nothing is recorded
        window.recording.required = [("st1", 0), ("st1", 7)]
        window.recording.take_edit.setText("gate-test")
        window.recording.start_button.click()
        assert "st1/7" in window.recording.message.text()
        window.recording.required = [("st1", 0), ("st1", 1)]
        window.recording.take_edit.setText("rally-01")
        window.recording.start_button.click()
        qtbot.waitUntil(lambda: (window.bridge.latest("recording") or {}).get("active") is True, timeout=30_000)
        qtbot.wait(2500)
        qtbot.waitUntil(lambda: "REC rally-01" in window.recording.counters.text(), timeout=30_000)
        window.recording.stop_button.click()
        qtbot.waitUntil(lambda: (window.bridge.latest("recording") or {}).get("active") is False, timeout=30_000)
        files = window.bridge.latest("recording")["files"]
        take_path = files[0]

        window.load_playback(take_path)
        pb = window.playback
        assert pb is not None and pb.duration_s > 2.0
        # scrub 1 s in: the views show the take's first second; data are the recorded readings
        window.seek_playback(1.0)
        window.tick()
        t, acc = window.store.rings[("st1", 1)].data()
        assert len(t) > 50 and t[0] >= pb.t_start_s - 1e-9 and t[-1] <= pb.t_start_s + 1.0 + 1e-9
        assert np.all((acc[:, 0] >= 1.0 - 0.05) & (acc[:, 0] <= 2.0 + 0.05))  # sensor 1 sawtooth in [1, 2)
        # seek to the middle: history is replaced by the window before the cursor
        window.seek_playback(pb.duration_s / 2)
        window.tick()
        t, _ = window.store.rings[("st1", 0)].data()
        assert t[-1] <= pb.cursor_s + 1e-9 and t[-1] > pb.cursor_s - 0.1
        # play: the cursor advances with the wall clock and the traces follow
        before = pb.cursor_s
        window.playbar.play_button.setChecked(True)
        qtbot.wait(600)
        assert pb.cursor_s > before + 0.3
        assert abs(window.store.latest_time() - pb.cursor_s) < 0.1
        window.back_to_live()
        qtbot.waitUntil(lambda: window.store.latest_time() is not None and window.store.latest_time() > pb.t_end_s,
                        timeout=30_000)
    finally:
        window.shutdown()
        client.close()
