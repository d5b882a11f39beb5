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
    for path in shots:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
