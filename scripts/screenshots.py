#!/usr/bin/env python3
"""Screenshots of the console for the docs: main view, device panel, calibration wizard, playback.

    QT_QPA_PLATFORM=offscreen .venv/bin/python scripts/screenshots.py [--out docs/screenshots]
    xvfb-run -a -s "-screen 0 1600x1000x24" .venv/bin/python scripts/screenshots.py

Runs the real demo (emulated stations replaying held-out mocap, synthetic camera, gateway, console) in this
process, records a short take and plays it back, grabbing each view as it goes."""
from __future__ import annotations

import argparse
import logging
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "screenshots")
    parser.add_argument("--warmup", type=float, default=10.0, help="seconds of live demo before the first grab")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")

    from gui.app import application, pump, save_grab
    from gui.demo.session import demo_session
    from gui.screens import capture_console

    application()
    with tempfile.TemporaryDirectory() as rec, demo_session(record_dir=Path(rec), duration_s=120) as session:
        window = session.window
        window.show()
        pump(args.warmup)
        shots = capture_console(window, args.out)

        # calibration wizard: sensors assigned from the device map, live stillness of the (walking) subject
        window.open_calibration()
        wizard = window.wizard
        pump(0.5)
        wizard.assign_from_mapping()
        pump(1.0)
        wizard.next_button.click()
        pump(1.5)
        shots.append(save_grab(wizard, args.out / "calibration.png"))
        wizard.close()

        # record a short take, then play it back through the same views with the scrubber half way
        window.tabs.setCurrentIndex(2)
        window.recording.take_edit.setText("screenshot-take")
        window.recording.start_button.click()
        pump(6.0)
        window.recording.stop_button.click()
        pump(1.0)
        state = window.bridge.latest("recording") or {}
        if not state.get("files"):
            print(f"screenshots: recording did not finish: {state}", file=sys.stderr)
            return 1
        window.load_playback(state["files"][0])
        window.seek_playback(window.playback.duration_s * 0.6)
        window.playbar.play_button.setChecked(True)
        pump(1.5)
        window.tabs.setCurrentIndex(2)
        pump(0.3)
        shots.append(save_grab(window, args.out / "playback.png"))
        window.tabs.setCurrentIndex(0)
        pump(0.5)
        shots.append(save_grab(window, args.out / "playback-traces.png"))
    shots.append(calibration_review(args.out / "calibration-review.png"))
    for path in shots:
        print(path)
    return 0


def calibration_review(path: Path) -> Path:
    """The wizard at its review step: a subject standing still in the N-pose (emulated still sensors, identity
    mounting) walked through assign -> placement -> N-pose capture -> tap skipped -> review, all via the gateway."""
    import tempfile
    import time

    from engine.mocap import SEED000_SENSORS
    from firmware_protocol.emulator import StationConfig
    from firmware_protocol.emulator.motion import StillSource
    from gateway.calibration.service import CalibrationService
    from gateway.calibration.wizard import SegmentSpec
    from gateway.client import GatewayClient
    from gateway.daemon import Gateway
    from firmware_protocol.emulator.stations import start_emulated_station
    from gui.app import pump, save_grab
    from gui.main_window import ConsoleWindow

    def wait(predicate, timeout_s: float) -> None:
        end = time.monotonic() + timeout_s
        while not predicate():
            if time.monotonic() > end:
                raise TimeoutError("calibration wizard did not get there")
            pump(0.2)

    station = start_emulated_station(StationConfig(station_id=1, n_sensors=6, autostart=True, noise_g=0.003),
                                     motion=StillSource(6))
    service = CalibrationService({name: SegmentSpec() for name in SEED000_SENSORS})
    with tempfile.TemporaryDirectory() as rec:
        gateway = Gateway([station.path], listen=("127.0.0.1", 0), record_dir=rec, calibration=service,
                          status_interval_s=0.5)
        gateway.start()
        client = GatewayClient(*gateway.address).connect()
        window = ConsoleWindow(client, sensor_segments={("st1", i): n for i, n in enumerate(SEED000_SENSORS)})
        try:
            window.open_calibration()
            wizard = window.wizard
            wait(lambda: wizard.state.get("step") == "assign", 10)
            wizard.assign_from_mapping()
            wait(lambda: all(x["segment"] for x in wizard.state.get("sensors", {}).values()), 10)
            wizard.next_button.click()
            wait(lambda: wizard.state.get("step") == "placement" and all(
                x["placement_ok"] for x in wizard.state["sensors"].values()), 10)
            wizard.next_button.click()
            wait(lambda: wizard.state.get("step") == "tap", 20)
            wizard.next_button.click()
            wait(lambda: wizard.state.get("step") == "review", 10)
            pump(0.5)
            return save_grab(wizard, path)
        finally:
            window.shutdown()
            client.close()
            gateway.stop()
            station.stop()


if __name__ == "__main__":
    sys.exit(main())
