"""Non-modal alarm banners: one line per active condition, coloured by level, dismissable, never a popup pile.

Conditions are keyed (`gui.health.Alarm.key`): a condition already shown is not repeated, and a status-derived
banner disappears by itself when its condition clears. Gateway ``event`` messages show for a fixed time."""
from __future__ import annotations

import time

from PySide6 import QtWidgets

from gui.health import Alarm

LEVEL_STYLE = {
    "alarm": "background:#8b1e1e; color:white;",
    "warning": "background:#8a6a12; color:white;",
    "info": "background:#2c4a6b; color:white;",
}
EVENT_BANNER_S = 8.0


class AlarmBar(QtWidgets.QWidget):
    def __init__(self, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self._layout = QtWidgets.QVBoxLayout(self)
        self._layout.setContentsMargins(0, 0, 0, 0)
        self._layout.setSpacing(1)
        self._banners: dict[str, QtWidgets.QWidget] = {}
        self._expires: dict[str, float] = {}
        self._dismissed: set[str] = set()

    def active(self) -> dict[str, str]:
        """key -> text of banners currently shown (for tests and the status bar)."""
        return {k: w.findChild(QtWidgets.QLabel).text() for k, w in self._banners.items()}

    def _show(self, key: str, level: str, text: str) -> None:
        if key in self._banners:
            self._banners[key].findChild(QtWidgets.QLabel).setText(text)
            return
        banner = QtWidgets.QFrame()
        banner.setStyleSheet(LEVEL_STYLE.get(level, LEVEL_STYLE["info"]))
        row = QtWidgets.QHBoxLayout(banner)
        row.setContentsMargins(6, 2, 6, 2)
        row.addWidget(QtWidgets.QLabel(text), 1)
        close = QtWidgets.QPushButton("×")
        close.setFlat(True)
        close.setFixedWidth(24)
        close.clicked.connect(lambda: self._dismiss(key))
        row.addWidget(close)
        self._layout.addWidget(banner)
        self._banners[key] = banner

    def _remove(self, key: str) -> None:
        banner = self._banners.pop(key, None)
        self._expires.pop(key, None)
        if banner is not None:
            banner.deleteLater()

    def _dismiss(self, key: str) -> None:
        """Operator acknowledged: hide until the condition clears and comes back."""
        self._dismissed.add(key)
        self._remove(key)

    def set_conditions(self, alarms: list[Alarm]) -> None:
        """Show exactly the current status-derived conditions (plus unexpired event banners)."""
        keys = {a.key for a in alarms}
        for key in [k for k in self._banners if k not in keys and k not in self._expires]:
            self._remove(key)
        self._dismissed &= keys
        for a in alarms:
            if a.key not in self._dismissed:
                self._show(a.key, a.level, a.message)
        now = time.monotonic()
        for key in [k for k, t in self._expires.items() if t < now]:
            self._remove(key)

    def add_event(self, level: str, source: str, message: str) -> None:
        key = f"event:{source}:{message}"
        self._show(key, level, f"{source}: {message}" if source else message)
        self._expires[key] = time.monotonic() + EVENT_BANNER_S
