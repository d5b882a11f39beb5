"""Per-athlete synthesis status: one block per athlete, its name in its skeleton's colour, the engine line wrapped
to the window's width and its faults in red below (`gui.athlete_status` says what each holds).

Why wrapped labels rather than the status bar: a status bar is one line and Qt cuts it at the window's edge, so
the second athlete and every error were invisible in each screenshot; here nothing is elided, the block grows."""
from __future__ import annotations

import html
import re

from PySide6 import QtCore, QtWidgets

from gui.athlete_status import AthleteStatus

FAULT_CSS = "color: #e03c3c; font-weight: bold;"
NOTE_CSS = "color: #b07a10;"


class AthleteStatusPanel(QtWidgets.QWidget):
    """Rows of (name, status text); `show_status` adds rows as athletes appear and updates them in place."""

    def __init__(self, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self._grid = QtWidgets.QGridLayout(self)
        self._grid.setContentsMargins(4, 0, 4, 0)
        self._grid.setHorizontalSpacing(10)
        self._grid.setVerticalSpacing(2)
        self._grid.setColumnStretch(1, 1)
        self._rows: dict[str, tuple[QtWidgets.QLabel, QtWidgets.QLabel]] = {}
        self.name_colours: dict[str, str] = {}  # athlete -> CSS colour of its skeleton (the console sets them)

    def show_status(self, statuses: list[AthleteStatus]) -> None:
        for status in statuses:
            _, text_label = self._row(status.name)
            text = _rich_text(status)
            if text != text_label.text():  # a rich-text layout per tick would cost the refresh its budget
                text_label.setText(text)
                text_label.setToolTip("\n".join(status.faults))

    def _row(self, name: str) -> tuple[QtWidgets.QLabel, QtWidgets.QLabel]:
        if name not in self._rows:
            colour = self.name_colours.get(name, "")
            name_label = QtWidgets.QLabel(f"■ {html.escape(name)}" if name else "synthesis")
            name_label.setStyleSheet(f"color: {colour}; font-weight: bold;" if colour else "font-weight: bold;")
            name_label.setAlignment(QtCore.Qt.AlignTop | QtCore.Qt.AlignLeft)
            text_label = QtWidgets.QLabel()
            text_label.setWordWrap(True)
            text_label.setTextFormat(QtCore.Qt.RichText)
            text_label.setTextInteractionFlags(QtCore.Qt.TextSelectableByMouse)
            text_label.setSizePolicy(QtWidgets.QSizePolicy.Ignored, QtWidgets.QSizePolicy.Preferred)
            row = len(self._rows)
            self._grid.addWidget(name_label, row, 0)
            self._grid.addWidget(text_label, row, 1)
            self._rows[name] = (name_label, text_label)
        return self._rows[name]

    def text(self, name: str) -> str:
        """The plain text shown for athlete `name` (tests, the bench)."""
        return html.unescape(re.sub(r"<[^>]+>", "", self._rows[name][1].text().replace("<br>", "\n")))

    def is_fault_shown(self, name: str) -> bool:
        """Whether athlete `name`'s row shows a fault in the fault colour."""
        return FAULT_CSS in self._rows[name][1].text()


def _rich_text(status: AthleteStatus) -> str:
    lines = [html.escape(status.summary)]
    lines += [f"<span style='{NOTE_CSS}'>{html.escape(note)}</span>" for note in status.notes]
    lines += [f"<span style='{FAULT_CSS}'>{html.escape(fault)}</span>" for fault in status.faults]
    return "<br>".join(lines)
