"""Live sensor traces (pyqtgraph) on the gateway clock, per sensor: accelerations x/y/z and |a| (g), or, from
sensors that stream them, orientation as roll/pitch/yaw (degrees, Z-up ZYX angles of the sensor -> device earth
quaternion: roll and pitch are the tilt the engine can trust, yaw is the device's own heading with no shared
north) or angular rate x/y/z and |w| (rad/s).

Data never touches Qt from the network thread: ``TraceStore.put`` is called from any thread and only
enqueues; the GUI thread's refresh tick calls ``drain`` (bounded work) then ``TracePanel.refresh`` which
min-max decimates each visible curve to about the plot's pixel width, so the draw cost does not depend on
the data rate (24 sensors x 100 Hz or 1 kHz alike).

The plots scroll like an oscilloscope: the x axis is fixed at seconds before the newest sample (-window .. 0)
and the data move, not the view. A view that follows the clock re-ranges six linked view boxes and regenerates
the time axis's ticks on every redraw (profiled: a third of a trace redraw); a fixed view does neither."""
from __future__ import annotations

from collections.abc import Hashable, Sequence

import numpy as np
import pyqtgraph as pg
from PySide6 import QtWidgets

from gui.ringbuffer import TraceStore, minmax_decimate
from gui.widgets.path_curve import PathCurve

RANGE_PRESETS_G = (2.0, 6.0, 12.0)
LEFT_AXIS_PX = 56
CHANNEL_PENS = (("x", (230, 80, 80)), ("y", (90, 200, 90)), ("z", (90, 140, 250)), ("|a|", (235, 235, 235)))
# what the panel shows: label -> (ring channel, y range or None = the range box's g)
VIEWS = {"acceleration (g)": ("acc_g", None), "orientation (deg)": ("quat_wxyz", 180.0),
         "angular rate (rad/s)": ("gyro_rps", 12.0)}


def orientation_angles_deg(quat_wxyz: np.ndarray) -> np.ndarray:
    """(N, 4) sensor -> earth (Z up) quaternions -> (N, 3) roll, pitch, yaw in degrees (ZYX: yaw about earth Z,
    then pitch, then roll), NaN rows stay NaN."""
    w, x, y, z = np.asarray(quat_wxyz, float).T
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.degrees(np.c_[roll, pitch, yaw])


def _view_values(channel: str, values: np.ndarray) -> np.ndarray:
    """Ring values -> the four drawn curves (x, y, z, magnitude; orientation: roll, pitch, yaw, nothing)."""
    if channel == "quat_wxyz":
        angles = orientation_angles_deg(values)
        return np.c_[angles, np.full(len(angles), np.nan)]
    return np.c_[values, np.linalg.norm(values, axis=1)]


def sensor_label(sensor: Hashable) -> str:
    """("st0", 3) -> "st0/3" (bridge keys are (station, sensor) tuples)."""
    return "/".join(map(str, sensor)) if isinstance(sensor, tuple) else str(sensor)


class TracePanel(QtWidgets.QWidget):
    """A column of linked plots, one per sensor of the selected group, with pause, range and window controls."""

    def __init__(self, store: TraceStore, window_s: float = 10.0, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.store = store
        self.window_s = window_s
        self.paused = False
        self.groups: dict[str, list[Hashable]] = {}
        self._plots: dict[Hashable, pg.PlotItem] = {}
        self._curves: dict[Hashable, list[PathCurve]] = {}
        self._t_end_drawn = 0.0  # gateway time (s) of x = 0 in the drawn curves (the newest sample then)
        self._event_lines: dict[int, list[tuple[pg.PlotItem, pg.InfiniteLine]]] = {}  # event seq -> lines

        self.group_box = QtWidgets.QComboBox()
        self.group_box.setSizeAdjustPolicy(QtWidgets.QComboBox.AdjustToContents)
        self.range_box = QtWidgets.QComboBox()
        for g in RANGE_PRESETS_G:
            self.range_box.addItem(f"±{g:g} g", g)
        self.range_box.setCurrentIndex(1)
        self.pause_button = QtWidgets.QPushButton("Pause")
        self.pause_button.setCheckable(True)
        self.window_box = QtWidgets.QComboBox()
        for w in (2.0, 5.0, 10.0, 30.0):
            self.window_box.addItem(f"{w:g} s", w)
        self.window_box.setCurrentIndex(2)
        self.view_box = QtWidgets.QComboBox()
        self.view_box.addItems(list(VIEWS))
        bar = QtWidgets.QHBoxLayout()
        for label, w in (("Sensors", self.group_box), ("Show", self.view_box), ("Range", self.range_box),
                         ("Window", self.window_box)):
            bar.addWidget(QtWidgets.QLabel(label))
            bar.addWidget(w)
        bar.addWidget(self.pause_button)
        bar.addStretch(1)
        self.graphics = pg.GraphicsLayoutWidget()
        layout = QtWidgets.QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addLayout(bar)
        layout.addWidget(self.graphics, 1)

        self.group_box.currentTextChanged.connect(self._show_group)
        self.range_box.currentIndexChanged.connect(lambda _: self._apply_range())
        self.view_box.currentTextChanged.connect(lambda _: self._apply_range())
        self.pause_button.toggled.connect(self.set_paused)
        self.window_box.currentIndexChanged.connect(lambda _: self.set_window_s(self.window_box.currentData()))

    # -- configuration -----------------------------------------------------------------------------------
    def set_groups(self, groups: dict[str, Sequence[Hashable]]) -> None:
        """Sensor groups (e.g. one per base station) selectable in the combo box; shows the first."""
        self.groups = {k: list(v) for k, v in groups.items()}
        current = self.group_box.currentText()
        self.group_box.blockSignals(True)
        self.group_box.clear()
        self.group_box.addItems(list(self.groups))
        self.group_box.blockSignals(False)
        self._show_group(current if current in self.groups else next(iter(self.groups), ""))
        if current in self.groups:
            self.group_box.setCurrentText(current)

    def _show_group(self, name: str) -> None:
        self.graphics.clear()
        self._plots.clear()
        self._curves.clear()
        self._event_lines.clear()
        first = None
        sensors = self.groups.get(name, [])
        for row, sensor in enumerate(sensors):
            plot = self.graphics.addPlot(row=row, col=0)
            plot.setLabel("left", sensor_label(sensor))  # values in g (the range box says so); short labels fit
            # one left-axis width for all: linked x views of equal width show the same seconds exactly
            plot.getAxis("left").setWidth(LEFT_AXIS_PX)
            if row < len(sensors) - 1:
                plot.hideAxis("bottom")  # one shared time axis at the bottom saves vertical space
            else:
                plot.setLabel("bottom", "seconds before the newest sample")
                plot.getAxis("bottom").enableAutoSIPrefix(False)
            # no grid: pyqtgraph draws it inside the axis QPicture, replayed on every paint (7 ms per axis)
            plot.setMenuEnabled(False)
            plot.disableAutoRange()  # ranges are set explicitly; auto-ranging re-scans every curve per frame
            if first is None:
                first = plot
                legend = plot.addLegend(offset=(-5, 1), colCount=4, labelTextSize="7pt")
                for name, colour in CHANNEL_PENS:
                    legend.addItem(pg.PlotDataItem(pen=pg.mkPen(colour, width=1)), name)
            else:
                plot.setXLink(first)  # pan / zoom together while paused
            curves = [PathCurve(pg.mkPen(c, width=1)) for _, c in CHANNEL_PENS]
            for curve in curves:
                plot.addItem(curve)
            self._curves[sensor] = curves
            self._plots[sensor] = plot
        self._apply_range()
        self._apply_window()

    def _apply_range(self) -> None:
        fixed = VIEWS[self.view_box.currentText()][1]
        limit = self.range_box.currentData() if fixed is None else fixed
        self.range_box.setEnabled(fixed is None)
        for plot in self._plots.values():
            plot.setYRange(-limit, limit, padding=0.02)

    def set_window_s(self, window_s: float) -> None:
        """Show the last `window_s` seconds."""
        self.window_s = float(window_s)
        self._apply_window()

    def _apply_window(self) -> None:
        if self._plots:
            next(iter(self._plots.values())).setXRange(-self.window_s, 0.0, padding=0)

    def set_view(self, label: str) -> None:
        """Show accelerations, orientation or angular rate (a `VIEWS` label)."""
        self.view_box.setCurrentText(label)

    def set_range_g(self, g: float) -> None:
        self.range_box.setCurrentIndex(RANGE_PRESETS_G.index(g))

    def set_paused(self, paused: bool) -> None:
        """Paused: curves freeze and the x axis is free to zoom/pan; data keeps buffering underneath. Resuming
        puts the view back on the last `window_s` seconds."""
        self.paused = paused
        self.pause_button.setChecked(paused)
        self.pause_button.setText("Resume" if paused else "Pause")
        for plot in self._plots.values():
            plot.setMouseEnabled(x=paused, y=False)
        if not paused:
            self._apply_window()

    # -- drawing ------------------------------------------------------------------------------------------
    def visible_sensors(self) -> list[Hashable]:
        return list(self._plots)

    def refresh(self) -> None:
        """Redraw visible curves from the rings (GUI thread, called by the refresh tick)."""
        self._draw_events()
        if self.paused:
            return
        t_end = self.store.latest_time()
        if t_end is None:
            return
        self._t_end_drawn = t_end
        t0 = t_end - self.window_s
        width_px = max(200, self.graphics.width())
        channel = VIEWS[self.view_box.currentText()][0]
        for sensor, curves in self._curves.items():
            ring = self.store.rings.get(sensor) if channel == "acc_g" else \
                self.store.channel_rings.get((sensor, channel))
            if ring is None or not ring.count:  # (a sensor that does not stream this channel: nothing drawn)
                for curve in curves:
                    curve.setData(np.zeros(0), np.zeros(0))
                continue
            t, values = ring.data()
            i0 = int(np.searchsorted(t, t0))
            vals = _view_values(channel, values[i0:])
            td, vd = minmax_decimate(t[i0:], vals, 2 * width_px)
            for k, curve in enumerate(curves):
                finite = np.isfinite(vd[:, k])  # NaN must not reach the path
                curve.setData(td[finite] - t_end, vd[finite, k])
        for lines in self._event_lines.values():
            for _, line in lines:
                line.setValue(line.t_s - t_end)

    def _draw_events(self) -> None:
        """Vertical marker lines for events (taps, calibration steps, gateway events) on every visible plot;
        lines of events the store has dropped (old, or history reset by a seek) are removed."""
        current = {seq for seq, _, _ in self.store.events}
        for seq in [q for q in self._event_lines if q not in current]:
            for plot, line in self._event_lines.pop(seq):
                plot.removeItem(line)
        for seq, t_s, label in self.store.events:
            if seq in self._event_lines:
                continue
            lines = []
            for plot in self._plots.values():
                line = pg.InfiniteLine(pos=t_s - self._t_end_drawn, angle=90, pen=pg.mkPen((250, 200, 60), width=1), label=label,
                                       labelOpts={"position": 0.9, "color": (250, 200, 60)})
                line.t_s = t_s  # gateway time: `refresh` moves the line as the newest sample moves
                plot.addItem(line)
                lines.append((plot, line))
            self._event_lines[seq] = lines

    def curve_data(self, sensor: Hashable, channel: int) -> tuple[np.ndarray, np.ndarray]:
        """What is currently drawn for ``sensor`` curve 0..3 (x, y, z, |a| / roll, pitch, yaw / x, y, z, |w|),
        x on the gateway clock (s): for tests and screenshots."""
        curve = self._curves[sensor][channel]
        return curve.xData + self._t_end_drawn, curve.yData
