"""Calibration wizard window driving the gateway's calibration workflow (gateway.calibration.service).

The gateway owns the state machine (assign -> placement -> npose -> tap -> review -> done) and publishes a
snapshot whenever it changes; this window only renders the snapshot and sends the operator's actions
(assign / confirm / redo / reset / save) through the console's request runner, so it never blocks on the
network and a second console sees the same wizard. Non-modal: the operator keeps watching traces meanwhile."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from PySide6 import QtCore, QtGui, QtWidgets

STEP_TITLES = {
    "assign": "1 Assign sensors", "placement": "2 Placement check", "npose": "3 N-pose",
    "tap": "4 Sync tap", "review": "5 Review", "done": "Done",
}
STEP_HELP = {
    "assign": "Put each sensor on its body segment (or take the device panel's mapping), then Next.",
    "placement": "Check each sensor's tilt against the book orientation; fix red ones, then Next.",
    "npose": "Stand upright, arms by the sides, palms in. Hold still: capture starts by itself.",
    "tap": "Tap one sensor sharply (sync event for the camera lag check) — or Next to skip.",
    "review": "Per-sensor result and overall quality. Accept, or redo one step.",
    "done": "Calibration accepted. Save it with the take.",
}
SENSOR_COLUMNS = ("sensor", "segment", "stillness", "std g", "tilt °", "placement", "result", "quality notes")


class PosePictogram(QtWidgets.QWidget):
    """Stick figure of the pose the current step asks for (N-pose; arms out for nothing else yet; a tap mark)."""

    def __init__(self, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.step = "assign"
        self.setMinimumSize(90, 160)

    def set_step(self, step: str) -> None:
        if step != self.step:
            self.step = step
            self.update()

    def paintEvent(self, _event: QtGui.QPaintEvent) -> None:
        p = QtGui.QPainter(self)
        p.setRenderHint(QtGui.QPainter.Antialiasing)
        s = min(self.width() / 90.0, self.height() / 160.0)
        p.scale(s, s)
        active = self.step in ("npose", "placement", "tap")
        pen = QtGui.QPen(QtGui.QColor(255, 160, 40) if active else QtGui.QColor(140, 140, 140), 4)
        pen.setCapStyle(QtCore.Qt.RoundCap)
        p.setPen(pen)
        p.drawEllipse(QtCore.QPointF(45, 16), 9, 10)
        lines = [((45, 27), (45, 85)), ((45, 85), (36, 150)), ((45, 85), (54, 150)),  # trunk, legs
                 ((45, 34), (33, 40)), ((45, 34), (57, 40)),                           # shoulders
                 ((33, 40), (30, 88)), ((57, 40), (60, 88))]                           # arms by the sides
        for a, b in lines:
            p.drawLine(QtCore.QPointF(*a), QtCore.QPointF(*b))
        if self.step == "tap":
            p.setPen(QtGui.QPen(QtGui.QColor(250, 220, 60), 2))
            for dx, dy in ((-8, -6), (8, -6), (0, -10)):
                p.drawLine(QtCore.QPointF(60, 88), QtCore.QPointF(60 + dx, 88 + dy))
        p.end()


class CalibrationWizard(QtWidgets.QDialog):
    """``request(action, **args)`` sends a calibration action (the console runs it off the GUI thread and
    calls `request_done`); `show_state` takes the latest snapshot published by the gateway."""

    def __init__(self, request: Callable[..., None], mapping: dict[tuple[str, int], str] | None = None,
                 parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Calibration")
        self.setModal(False)
        self.resize(860, 520)
        self._request = request
        self.mapping = mapping or {}
        self.state: dict[str, Any] = {}
        self.steps_bar = QtWidgets.QLabel()
        self.steps_bar.setTextFormat(QtCore.Qt.RichText)
        self.help = QtWidgets.QLabel()
        self.help.setWordWrap(True)
        self.countdown = QtWidgets.QLabel("")
        self.countdown.setStyleSheet("font-size: 28px; font-weight: bold; color: #ffa030;")
        self.phase = QtWidgets.QLabel("")
        self.pictogram = PosePictogram()
        self.table = QtWidgets.QTableWidget(0, len(SENSOR_COLUMNS))
        self.table.setHorizontalHeaderLabels(list(SENSOR_COLUMNS))
        self.table.verticalHeader().setVisible(False)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.quality = QtWidgets.QLabel("quality: –")
        self.quality.setStyleSheet("font-size: 16px;")
        self.messages = QtWidgets.QPlainTextEdit()
        self.messages.setReadOnly(True)
        self.messages.setMaximumBlockCount(50)
        self.messages.setFixedHeight(70)
        self.assign_button = QtWidgets.QPushButton("Assign from device map")
        self.next_button = QtWidgets.QPushButton("Next / Accept")
        self.redo_box = QtWidgets.QComboBox()
        self.redo_box.addItems(["placement", "npose", "tap", "assign"])
        self.redo_button = QtWidgets.QPushButton("Redo step")
        self.reset_button = QtWidgets.QPushButton("Start over")
        self.error = QtWidgets.QLabel("")
        self.error.setStyleSheet("color: #e05050;")

        top = QtWidgets.QHBoxLayout()
        left = QtWidgets.QVBoxLayout()
        left.addWidget(self.pictogram, 1)
        left.addWidget(self.countdown, 0, QtCore.Qt.AlignHCenter)
        top.addLayout(left)
        right = QtWidgets.QVBoxLayout()
        right.addWidget(self.steps_bar)
        right.addWidget(self.help)
        right.addWidget(self.phase)
        right.addWidget(self.table, 1)
        right.addWidget(self.quality)
        top.addLayout(right, 1)
        buttons = QtWidgets.QHBoxLayout()
        for w in (self.assign_button, self.next_button, self.redo_box, self.redo_button, self.reset_button):
            buttons.addWidget(w)
        buttons.addStretch(1)
        layout = QtWidgets.QVBoxLayout(self)
        layout.addLayout(top, 1)
        layout.addWidget(self.messages)
        layout.addWidget(self.error)
        layout.addLayout(buttons)

        self.assign_button.clicked.connect(self.assign_from_mapping)
        self.next_button.clicked.connect(lambda: self._request("confirm"))
        self.redo_button.clicked.connect(lambda: self._request("redo", step=self.redo_box.currentText()))
        self.reset_button.clicked.connect(lambda: self._request("reset"))
        self._request("state")

    # -- actions -----------------------------------------------------------------------------------------------
    def assign_from_mapping(self) -> None:
        """Assign every mapped sensor ("st1/0" -> placement name) the wizard knows a segment for."""
        known = set(self.state.get("unassigned_segments", [])) | {
            s.get("segment") for s in self.state.get("sensors", {}).values() if s.get("segment")}
        for (station, sensor), segment in sorted(self.mapping.items()):
            if not known or segment in known:
                self._request("assign", sensor=f"{station}/{sensor}", segment=segment)

    def request_done(self, tag: str, result: Any, error: str) -> None:
        """Outcome of a request sent through the console's runner (tag ``calibration:<action>``)."""
        if error:
            self.error.setText(error)
            return
        self.error.setText("")
        if isinstance(result, dict) and "accepted" in result:
            if not result["accepted"] and result.get("state", {}).get("messages"):
                self.error.setText(result["state"]["messages"][-1])
            result = result.get("state")
        if isinstance(result, dict) and "step" in result:
            self.show_state({"state": result})

    # -- rendering ---------------------------------------------------------------------------------------------
    def show_state(self, message: dict[str, Any] | None) -> None:
        """Render a ``calibration`` message header (``{"state": snapshot}``) or a bare snapshot."""
        if not message:
            return
        state = message.get("state", message)
        if not isinstance(state, dict) or "step" not in state or state == self.state:
            return
        self.state = state
        step = state["step"]
        done = set(state.get("completed", []))
        parts = []
        for s in state.get("steps", []):
            title = STEP_TITLES.get(s, s)
            if s == step:
                parts.append(f"<b style='color:#ffa030'>{title}</b>")
            elif s in done:
                parts.append(f"<span style='color:#50c070'>✓ {title}</span>")
            else:
                parts.append(f"<span style='color:#888'>{title}</span>")
        self.steps_bar.setText(" → ".join(parts))
        # the gateway states the pose its segment specs expect (N-pose by default, T-pose as an option)
        pose_help = state.get("pose_instructions") if step == "npose" else None
        self.help.setText(pose_help or STEP_HELP.get(step, ""))
        phase = state.get("phase", "")
        rejections = state.get("rejections", 0)
        self.phase.setText(f"phase: {phase.replace('_', ' ')}" + (f"   (rejected {rejections}×)" if rejections else ""))
        countdown = state.get("countdown_s")
        self.countdown.setText("" if countdown is None else f"{countdown:.1f} s")
        self.pictogram.set_step(step)
        self._fill_table(state.get("sensors", {}))
        q = state.get("quality") or {}
        verdict = "PASS" if q.get("passed") else ("FAIL" if state.get("sensors") and q.get("grade") != "none" else "–")
        colour = "#50c070" if q.get("passed") else "#e05050" if verdict == "FAIL" else "#aaa"
        self.quality.setText(f"quality: <b>{q.get('score', 0):.0f}/100</b> ({q.get('grade', 'none')}) "
                             f"<b style='color:{colour}'>{verdict}</b>")
        self.messages.setPlainText("\n".join(state.get("messages", [])[-6:]))
        self.assign_button.setEnabled(step == "assign")

    def _fill_table(self, sensors: dict[str, Any]) -> None:
        self.table.setRowCount(len(sensors))
        for row, (sid, info) in enumerate(sorted(sensors.items())):
            meter = QtWidgets.QProgressBar()
            meter.setRange(0, 100)
            value = int(round(100 * float(info.get("stillness") or 0.0)))
            meter.setValue(value)
            meter.setFormat("still" if value >= 100 else f"{value}%")
            chunk = "#40b060" if value >= 100 else "#d0a030" if value > 0 else "#c04040"
            meter.setStyleSheet(f"QProgressBar::chunk {{ background: {chunk}; }}")
            self.table.setCellWidget(row, 2, meter)
            passed = info.get("passed")
            placement_ok = info.get("placement_ok")
            texts = [sid, info.get("segment") or "–", "", _fmt(info.get("std_g"), ".3f"), _fmt(info.get("tilt_deg"), ".0f"),
                     "–" if placement_ok is None else ("ok" if placement_ok else "check"),
                     "–" if passed is None else ("pass" if passed else "FAIL"),
                     "; ".join(info.get("reasons") or info.get("placement_reasons") or [])]
            for col, text in enumerate(texts):
                if col == 2:
                    continue
                item = QtWidgets.QTableWidgetItem(text)
                if col == 6 and passed is not None:
                    item.setForeground(QtGui.QColor(80, 190, 110) if passed else QtGui.QColor(220, 80, 80))
                self.table.setItem(row, col, item)
        self.table.resizeColumnsToContents()


def _fmt(value: Any, spec: str) -> str:
    return "–" if value is None else format(float(value), spec)
