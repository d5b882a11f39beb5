"""Qt application plumbing shared by `courtside console`, `courtside demo`, the screenshot script and the bench:
create the QApplication, run for a fixed duration (CI/Xvfb), and save window grabs."""
from __future__ import annotations

import logging
import os
import sys
from pathlib import Path

from PySide6 import QtCore, QtWidgets

log = logging.getLogger("courtside.console")


def application() -> QtWidgets.QApplication:
    """The process's QApplication (created once, Fusion style so screenshots look the same everywhere).

    Without any display (no $DISPLAY / $WAYLAND_DISPLAY, no QT_QPA_PLATFORM) Qt would abort at start; we fall
    back to the offscreen platform instead, so `--duration/--screenshots` runs still work on a bare server."""
    app = QtWidgets.QApplication.instance()
    if app is None:
        if not any(os.environ.get(v) for v in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")):
            log.warning("no display found: running offscreen (nothing is shown; use --screenshots, or ./demo.sh "
                        "which starts Xvfb)")
            os.environ["QT_QPA_PLATFORM"] = "offscreen"
        app = QtWidgets.QApplication(sys.argv[:1])
        app.setApplicationName("Courtside")
        app.setStyle("Fusion")
    return app


def pump(seconds: float) -> None:
    """Run the event loop for ``seconds`` (used where a nested loop is simpler than timers: scripts, bench)."""
    app = application()
    loop = QtCore.QEventLoop()
    QtCore.QTimer.singleShot(int(seconds * 1000), loop.quit)
    loop.exec()
    app.processEvents()


def save_grab(widget: QtWidgets.QWidget, path: Path) -> Path:
    """PNG of a widget as currently drawn (works offscreen and under Xvfb)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not widget.grab().save(str(path)):
        raise OSError(f"{path}: could not write PNG")
    return path


def run(window: QtWidgets.QWidget, duration_s: float | None) -> int:
    """Show ``window`` and run until it closes, or for ``duration_s`` then close it."""
    app = application()
    window.show()
    if duration_s is not None:
        QtCore.QTimer.singleShot(int(duration_s * 1000), window.close)
    app.exec()
    return 0
