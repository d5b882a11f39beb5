"""The console against a real gateway: emulated stations on ptys -> gateway -> TCP -> console widgets (offscreen).

Ground truth comes from the emulator: still sensors read exactly gravity in their frame; a "moving" subject
is a trace with a known still part followed by shaking."""
from __future__ import annotations

import numpy as np
import pytest

from firmware_protocol.emulator.motion import StillSource, TraceSource
from gateway.calibration.service import CalibrationService
from gateway.calibration.wizard import SegmentSpec
from gateway.client import GatewayClient
from gui.main_window import ConsoleWindow

SEGMENTS = ("left_forearm", "right_forearm", "chest")


@pytest.fixture()
def console(qtbot):
    windows = []

    def open_console(gateway, **kwargs):
        client = GatewayClient(*gateway.address).connect()
        window = ConsoleWindow(client, sensor_segments={("st1", i): s for i, s in enumerate(SEGMENTS)}, **kwargs)
        qtbot.addWidget(window)
        window.resize(1200, 800)
        window.show()
        windows.append((window, client))
        return window

    yield open_console
    for window, client in windows:
        window.shutdown()
        client.close()


def test_traces_devices_and_identify_on_live_gateway(live_gateway, console, qtbot):
    gateway, _ = live_gateway(StillSource(3), 3)
    window = console(gateway)
    keys = [("st1", i) for i in range(3)]
    qtbot.waitUntil(lambda: all(k in window.store.rings and window.store.rings[k].count > 50 for k in keys), timeout=10_000)
    qtbot.waitUntil(lambda: len(window.traces.curve_data(keys[0], 3)[0]) > 20, timeout=30_000)
    for k in keys:
        _, mag = window.traces.curve_data(k, 3)
        np.testing.assert_allclose(mag, 1.0, atol=0.05)  # a still sensor reads 1 g
    qtbot.waitUntil(lambda: window.devices.row_texts(("sensor", "st1", 2))[1] == "streaming", timeout=10_000)
    row = window.devices.row_texts(("sensor", "st1", 0))
    assert row[12] == "left_forearm" and row[4].endswith("/ 100")
    qtbot.waitUntil(lambda: window.devices.row_texts(("sensor", "st1", 0))[2] != "–", timeout=10_000)
    assert 90 <= float(window.devices.row_texts(("sensor", "st1", 0))[2]) <= 100  # STATUS battery % of a fresh station
    # identify goes to the emulated station and comes back ACKed, off the GUI thread
    results = []
    window.requests.done.connect(lambda tag, result, error: results.append((tag, result, error)))
    window.devices.identify_requested.emit("st1", 1)
    qtbot.waitUntil(lambda: bool(results), timeout=30_000)
    tag, result, error = results[0]
    assert tag == "identify" and error == "" and result["acked"] is True


def run_wizard_until(window, qtbot, predicate, timeout_ms):
    qtbot.waitUntil(lambda: bool(window.wizard.state) and predicate(window.wizard.state), timeout=timeout_ms)
    return window.wizard.state


def test_wizard_completes_on_a_still_subject(live_gateway, console, qtbot):
    service = CalibrationService({name: SegmentSpec() for name in SEGMENTS})
    gateway, _ = live_gateway(StillSource(3), 3, calibration=service)  # identity: sensor Y up, as specified
    window = console(gateway)
    window.open_calibration()
    wizard = window.wizard
    run_wizard_until(window, qtbot, lambda s: s["step"] == "assign", 30_000)
    wizard.assign_button.click()
    run_wizard_until(window, qtbot, lambda s: len([x for x in s["sensors"].values() if x["segment"]]) == 3, 30_000)
    wizard.next_button.click()  # -> placement
    run_wizard_until(window, qtbot, lambda s: s["step"] == "placement" and all(
        x["placement_ok"] for x in s["sensors"].values()), 8_000)
    wizard.next_button.click()  # -> npose: captures by itself once everyone is still
    state = run_wizard_until(window, qtbot, lambda s: s["step"] == "tap", 15_000)
    assert state["rejections"] == 0
    wizard.next_button.click()  # skip the tap -> review
    state = run_wizard_until(window, qtbot, lambda s: s["step"] == "review", 30_000)
    assert state["quality"]["passed"] and state["quality"]["score"] > 70
    assert all(x["passed"] for x in state["sensors"].values())
    assert "PASS" in wizard.quality.text()
    wizard.next_button.click()
    run_wizard_until(window, qtbot, lambda s: s["step"] == "done", 30_000)


def shaking_subject(n_sensors: int, still_s: float = 1.6, shake_s: float = 1.4, fps: float = 100.0) -> TraceSource:
    """Gravity along sensor Y for ``still_s``, then a 4 Hz +-0.4 g shake for ``shake_s`` (looped)."""
    t = np.arange(int((still_s + shake_s) * fps)) / fps
    acc = np.zeros((len(t), n_sensors, 3))
    acc[..., 1] = 1.0
    moving = t >= still_s
    acc[moving, :, 0] += 0.4 * np.sin(2 * np.pi * 4.0 * t[moving])[:, None]
    return TraceSource(acc, fps)


def test_wizard_rejects_a_moving_subject(live_gateway, console, qtbot):
    service = CalibrationService({name: SegmentSpec() for name in SEGMENTS})
    gateway, _ = live_gateway(shaking_subject(3), 3, calibration=service)
    window = console(gateway)
    client = window.client
    for i, name in enumerate(SEGMENTS):
        client.calibration("assign", sensor=f"st1/{i}", segment=name)
    assert client.calibration("confirm")["accepted"]          # -> placement
    qtbot.waitUntil(lambda: client.calibration("state")["step"] == "placement", timeout=30_000)
    qtbot.waitUntil(lambda: client.calibration("confirm")["accepted"], timeout=30_000)  # -> npose (when upright)
    window.open_calibration()
    # capture starts in each still phase and is rejected when the shaking begins; it never completes
    state = run_wizard_until(window, qtbot, lambda s: s["rejections"] >= 2, 20_000)
    assert state["step"] == "npose" and not state["quality"]["passed"]
    assert any("rejected" in m for m in state["messages"])
    assert "rejected" in window.wizard.phase.text()


def test_console_reconnects_when_the_gateway_comes_back(live_gateway, console, qtbot, tmp_path):
    from firmware_protocol.emulator import StationConfig
    from gateway.daemon import Gateway
    from firmware_protocol.emulator.stations import start_emulated_station

    first, _ = live_gateway(StillSource(3), 3)
    host, port = first.address
    window = console(first)
    qtbot.waitUntil(lambda: window.store.latest_time() is not None, timeout=10_000)
    first.stop()
    qtbot.waitUntil(lambda: "DISCONNECTED" in window.connection.text(), timeout=30_000)
    assert "gateway" in window.alarms.active()
    station = start_emulated_station(StationConfig(station_id=4, n_sensors=2, autostart=True), motion=StillSource(2))
    second = Gateway([station.path], listen=(host, port), record_dir=tmp_path / "rec2", status_interval_s=0.2)
    second.start()
    try:
        qtbot.waitUntil(lambda: ("st4", 1) in window.store.rings, timeout=15_000)
        assert "DISCONNECTED" not in window.connection.text()
        qtbot.waitUntil(lambda: "gateway" not in window.alarms.active(), timeout=30_000)
    finally:
        second.stop()
        station.stop()


def test_a_viewer_console_offers_no_control_the_gateway_would_refuse(tmp_path, qtbot):
    """Roles end to end: a gateway with an operator and a viewer secret on 127.0.0.6; the console connected with
    the viewer secret shows "viewer" and has calibration, recording and identify disabled (the gateway refuses
    them all); the operator's console has them enabled."""
    from firmware_protocol.emulator import StationConfig
    from gateway import auth
    from gateway.daemon import Gateway
    from firmware_protocol.emulator.stations import start_emulated_station

    secrets = auth.Secrets(auth.new_secret().encode(), auth.new_secret().encode())
    station = start_emulated_station(StationConfig(station_id=1, n_sensors=2, autostart=True), motion=StillSource(2))
    gateway = Gateway([station.path], listen=("127.0.0.6", 0), record_dir=tmp_path / "rec", status_interval_s=0.2,
                      secrets=secrets).start()
    windows = []
    try:
        for secret in (secrets.viewer, secrets.operator):
            window = ConsoleWindow(GatewayClient(*gateway.address, secret=secret).connect())
            qtbot.addWidget(window)
            windows.append(window)
            qtbot.waitUntil(lambda: window.devices.identify_button("st1", 1) is not None, timeout=30_000)
        (viewer, operator) = windows
        identify = lambda w: w.devices.identify_button("st1", 0)  # noqa: E731
        assert viewer.connection.text().endswith("(viewer: watch only)")
        assert not viewer.calibrate_button.isEnabled() and not viewer.recording.start_button.isEnabled()
        assert not identify(viewer).isEnabled() and "viewer" in viewer.recording.message.text()
        assert "viewer" not in operator.connection.text()
        assert operator.calibrate_button.isEnabled() and operator.recording.start_button.isEnabled()
        assert identify(operator).isEnabled()
    finally:
        for window in windows:
            window.shutdown()
            window.client.close()
        gateway.stop()
        station.stop()


def test_synthesis_starts_afresh_after_a_reconnect_instead_of_stepping_through_the_outage(tmp_path, qtbot):
    """The gateway restarts (service manager) under a running console: synthesis resumes on the new data; the
    frames of the outage are not pushed through the engine blind (before: every one of them, e.g. 12 s of
    frames after a real restart, reported as FALLING BEHIND while the engine worked them off)."""
    import time

    from engine.stream.registry import adapter
    from firmware_protocol.emulator import StationConfig
    from gateway.daemon import Gateway
    from firmware_protocol.emulator.stations import start_emulated_station
    from gui.engine_link import synthesis_setup

    def court(address):
        station = start_emulated_station(StationConfig(station_id=1, n_sensors=1, autostart=True),
                                         motion=StillSource(1))
        return station, Gateway([station.path], listen=address, record_dir=tmp_path / "rec",
                                status_interval_s=0.2).start()

    station, gateway = court(("127.0.0.6", 0))
    address = gateway.address
    window = ConsoleWindow(GatewayClient(*address).connect(),
                           synthesis=synthesis_setup(adapter("hmm").shipped_spec(), [("st1", 0)], lag_s=0.5))
    qtbot.addWidget(window)
    try:
        qtbot.waitUntil(lambda: window.worker.stats.frames_in > 30, timeout=30_000)
        gateway.stop()
        station.stop()
        qtbot.waitUntil(lambda: "DISCONNECTED" in window.connection.text(), timeout=30_000)
        time.sleep(3.0)  # the outage: 90 frames at 30 Hz without data
        t_back = time.monotonic()  # the gateway clock is this machine's CLOCK_MONOTONIC
        station, gateway = court(address)
        qtbot.waitUntil(lambda: window.reconnects == 1, timeout=30_000)
        pose_after = lambda: (p := window.worker.latest_pose()) is not None and p.t_s > t_back + 1.0  # noqa: E731
        qtbot.waitUntil(pose_after, timeout=30_000)
        assert window.worker.stats.frames_invalid < 15  # none of the outage's ~90+ frames
        assert window.worker.stats.error == ""
    finally:
        window.shutdown()
        window.client.close()
        gateway.stop()
        station.stop()
