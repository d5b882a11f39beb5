"""Recording controls (take name, start/stop, required-sensors gate, counters) and the playback transport
(open a take, play/pause, timeline scrubber)."""
from __future__ import annotations

import re
from typing import Any

from PySide6 import QtCore, QtWidgets

from gui.widgets import VIEWER_ONLY

TAKE_NAME = re.compile(r"^[A-Za-z0-9_.-]{1,100}$")  # what the gateway accepts (docs/gateway.md)
STREAMING_WITHIN_S = 1.0


def missing_required(status: dict[str, Any] | None, required: list[tuple[str, int]]) -> list[tuple[str, int]]:
    """Required sensors that are not streaming right now (no sample within 1 s of the status time)."""
    if not required:
        return []
    if not status:
        return list(required)
    now = status.get("t_host_s")
    live = set()
    for st in status.get("stations", []):
        if st.get("link") != "streaming":
            continue
        for s in st.get("sensors", []):
            last = s.get("last_t_host_s")
            if last is not None and now is not None and float(now) - float(last) <= STREAMING_WITHIN_S:
                live.add((str(st.get("station")), int(s.get("sensor"))))
    return [k for k in required if k not in live]


class RecordingPanel(QtWidgets.QGroupBox):
    start_requested = QtCore.Signal(str)
    stop_requested = QtCore.Signal()

    def __init__(self, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__("Recording", parent)
        self.take_edit = QtWidgets.QLineEdit("take-001")
        self.require_box = QtWidgets.QCheckBox("require all mapped sensors")
        self.require_box.setChecked(True)
        self.start_button = QtWidgets.QPushButton("● Record")
        self.stop_button = QtWidgets.QPushButton("■ Stop")
        self.stop_button.setEnabled(False)
        self.counters = QtWidgets.QLabel("not recording")
        self.message = QtWidgets.QLabel("")
        self.message.setStyleSheet("color:#e0a030;")
        form = QtWidgets.QGridLayout(self)
        form.addWidget(QtWidgets.QLabel("Take"), 0, 0)
        form.addWidget(self.take_edit, 0, 1)
        form.addWidget(self.start_button, 0, 2)
        form.addWidget(self.stop_button, 0, 3)
        form.addWidget(self.require_box, 1, 1)
        form.addWidget(self.counters, 2, 0, 1, 4)
        form.addWidget(self.message, 3, 0, 1, 4)
        self.start_button.clicked.connect(self._start_clicked)
        self.stop_button.clicked.connect(self.stop_requested)
        self.required: list[tuple[str, int]] = []
        self.status: dict[str, Any] | None = None
        self.allowed = True  # False for a viewer connection (the gateway refuses recording requests)

    def _start_clicked(self) -> None:
        take = self.take_edit.text().strip()
        if not TAKE_NAME.match(take):
            self.message.setText("take name: letters, digits, '_', '.', '-' only")
            return
        missing = missing_required(self.status, self.required) if self.require_box.isChecked() else []
        if missing:
            self.message.setText("refused: not streaming: " + ", ".join(f"{s}/{i}" for s, i in missing))
            return
        self.message.setText("")
        self.start_requested.emit(take)

    def set_allowed(self, allowed: bool) -> None:
        """Recording controls only for an operator connection; a viewer sees the counters and why."""
        self.allowed = allowed
        for button in (self.start_button, self.stop_button):
            button.setToolTip("" if allowed else VIEWER_ONLY)
        self.take_edit.setEnabled(allowed)
        self.message.setText("" if allowed else "viewer: " + VIEWER_ONLY)
        self.show_state(None, None)

    def show_state(self, state: dict[str, Any] | None, t_now_s: float | None) -> None:
        """Counters from the gateway's ``recording`` message."""
        active = bool(state and state.get("active"))
        self.start_button.setEnabled(self.allowed and not active)
        self.stop_button.setEnabled(self.allowed and active)
        if not state:
            return
        if active:
            dur = (t_now_s - float(state.get("started_t_host_s") or t_now_s)) if t_now_s is not None else 0.0
            self.counters.setText(f"REC {state.get('take')}  {dur:6.1f} s  samples {state.get('samples_written', 0)}  "
                                  f"{int(state.get('bytes_written', 0)) / 1e6:.2f} MB  → {state.get('path', '')}")
        else:
            self.counters.setText(f"stopped: {state.get('take') or '-'}  samples {state.get('samples_written', 0)}")

    def show_error(self, text: str) -> None:
        self.message.setText(text)


class PlaybackBar(QtWidgets.QGroupBox):
    """Transport for a loaded take: open, play/pause, scrubber in milliseconds of take time."""

    open_requested = QtCore.Signal()
    play_toggled = QtCore.Signal(bool)
    seek_requested = QtCore.Signal(float)  # seconds from the take start

    def __init__(self, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__("Playback", parent)
        self.open_button = QtWidgets.QPushButton("Open take…")
        self.play_button = QtWidgets.QPushButton("▶ Play")
        self.play_button.setCheckable(True)
        self.play_button.setEnabled(False)
        self.live_button = QtWidgets.QPushButton("Back to live")
        self.live_button.setEnabled(False)
        self.slider = QtWidgets.QSlider(QtCore.Qt.Horizontal)
        self.slider.setEnabled(False)
        self.time_label = QtWidgets.QLabel("–")
        row = QtWidgets.QHBoxLayout(self)
        for w in (self.open_button, self.play_button, self.slider, self.time_label, self.live_button):
            row.addWidget(w, 1 if w is self.slider else 0)
        self.open_button.clicked.connect(self.open_requested)
        self.play_button.toggled.connect(self._toggled)
        self.slider.sliderMoved.connect(lambda v: self.seek_requested.emit(v / 1000.0))
        self._duration_s = 0.0

    def _toggled(self, on: bool) -> None:
        self.play_button.setText("❚❚ Pause" if on else "▶ Play")
        self.play_toggled.emit(on)

    def loaded(self, name: str, duration_s: float) -> None:
        self.setTitle(f"Playback: {name}")
        self._duration_s = duration_s
        self.slider.setRange(0, int(duration_s * 1000))
        for w in (self.slider, self.play_button, self.live_button):
            w.setEnabled(True)

    def show_position(self, t_rel_s: float) -> None:
        if not self.slider.isSliderDown():
            self.slider.setValue(int(t_rel_s * 1000))
        self.time_label.setText(f"{t_rel_s:6.2f} / {self._duration_s:.2f} s")
