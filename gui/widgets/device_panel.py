"""Device panel: every base station and sensor with link/battery/RSSI/rate/loss/CRC/clock/sync state, an
identify (blink) button per sensor, and the sensor -> body-segment mapping on a body diagram per athlete.

Readability (issue 30): the sync cell's colour says how good and its text why ("locked", "warming up",
"residual 7.2 ms"), never the colour's name; a station's clock offset is its power-on time, huge and harmless, so
it is shown in seconds with a tooltip saying so; identify buttons keep their own width."""
from __future__ import annotations

from typing import Any

from PySide6 import QtCore, QtGui, QtWidgets

from gui.health import Sync, sensor_sync, sync_reason, sync_status
from gui.widgets import VIEWER_ONLY

SYNC_RANK = [Sync.GREEN, Sync.AMBER, Sync.RED]  # better to worse
SYNC_QCOLOR = {Sync.GREEN: QtGui.QColor(40, 170, 70), Sync.AMBER: QtGui.QColor(220, 160, 30),
               Sync.RED: QtGui.QColor(200, 50, 50)}
COLUMNS = ("device", "link", "battery %", "RSSI dBm", "rate / nominal Hz", "loss %", "lost", "CRC err",
           "clock offset s", "skew ppm", "residual ms", "sync", "segment", "")
OFFSET_TIP = ("Station clock minus gateway clock, in seconds. Any value is normal: a station counts from its own "
              "power-on. What matters is the sync cell (locked) and a small residual.")
HEADER_TIPS = {8: OFFSET_TIP, 9: "how fast the station's clock runs against the gateway's (parts per million)",
               10: "scatter of the station's packet times about the fitted clock: under 5 ms is locked",
               11: "clock sync: locked (green), warming up or residual elevated (amber), link lost or residual "
                   "too large to trust sample times (red)"}
LABEL_PX = 11  # body-diagram label size on screen, whatever the diagram's scale

# Body diagram: segment -> polyline in a 100 x 200 box (x right, y down), front view.
BODY_SEGMENTS: dict[str, tuple[tuple[float, float], ...]] = {
    "head": ((50, 10), (50, 30)),
    "chest": ((50, 40), (50, 75)),
    "pelvis": ((38, 95), (62, 95)),
    "left_upper_arm": ((68, 42), (78, 75)),
    "right_upper_arm": ((32, 42), (22, 75)),
    "left_forearm": ((78, 75), (84, 105)),
    "right_forearm": ((22, 75), (16, 105)),
    "left_thigh": ((58, 98), (62, 145)),
    "right_thigh": ((42, 98), (38, 145)),
    "left_shin": ((62, 145), (63, 190)),
    "right_shin": ((38, 145), (37, 190)),
}
_ALIASES = {"hips": "pelvis", "root": "pelvis", "spine": "chest", "torso": "chest", "sternum": "chest",
            "trunk": "chest", "wrist": "forearm", "hand": "forearm", "lowerarm": "forearm", "forearm": "forearm",
            "ankle": "shin", "foot": "shin", "leg": "shin", "shank": "shin", "upleg": "thigh", "thigh": "thigh",
            "knee": "shin", "shin": "shin", "arm": "upper_arm", "shoulder": "upper_arm", "neck": "head",
            "head": "head", "back": "pelvis", "lumbar": "pelvis", "pelvis": "pelvis", "chest": "chest"}


def segment_for(name: str) -> str | None:
    """Map a placement/joint name ("LeftWrist", "l_ankle", "pelvis") to a diagram segment, if recognisable."""
    low = name.lower().replace("-", "_")
    side = "left_" if low.startswith(("left", "l_")) or "left" in low else (
        "right_" if low.startswith(("right", "r_")) or "right" in low else "")
    for word, seg in sorted(_ALIASES.items(), key=lambda kv: -len(kv[0])):
        if word in low.replace("_", ""):
            full = seg if seg in BODY_SEGMENTS else side + seg
            return full if full in BODY_SEGMENTS else None
    return None


class BodyDiagram(QtWidgets.QWidget):
    """Front-view stick body of one athlete; segments carrying a sensor are drawn thick in that sensor's health
    colour and labelled with the sensor (station/index) beside the segment, on the side it is on."""

    def __init__(self, title: str = "", parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.title = title
        self.segment_state: dict[str, tuple[str, Sync]] = {}  # segment -> (sensor label, health)
        self.setMinimumSize(220, 240)

    def set_state(self, state: dict[str, tuple[str, Sync]]) -> None:
        self.segment_state = state
        self.update()

    def paintEvent(self, _event: QtGui.QPaintEvent) -> None:
        p = QtGui.QPainter(self)
        p.setRenderHint(QtGui.QPainter.Antialiasing)
        top = 18 if self.title else 0
        font = QtGui.QFont(self.font())
        font.setPixelSize(LABEL_PX)
        p.setFont(font)
        # labels in unscaled pixels (readable at any size) on either side; the figure (100 wide) between them
        widths = {side: max([p.fontMetrics().horizontalAdvance(label) for seg, (label, _) in self.segment_state.items()
                             if label and seg in BODY_SEGMENTS and _label_side(seg) == side], default=0)
                  for side in ("left", "right", "below")}
        room = self.width() - widths["left"] - widths["right"] - 24
        scale = max(0.2, min(room / 100.0, (self.height() - top - LABEL_PX - 4) / 205.0))
        x0 = widths["left"] + 12 + max(0.0, room - 100 * scale) / 2
        figure = QtGui.QTransform().translate(x0, top).scale(scale, scale)
        if self.title:
            p.setPen(self.palette().color(QtGui.QPalette.WindowText))
            p.drawText(QtCore.QRectF(0, 0, self.width(), top), QtCore.Qt.AlignCenter, self.title)
        p.setTransform(figure)
        p.setPen(QtGui.QPen(QtGui.QColor(120, 120, 120), 2))
        p.drawEllipse(QtCore.QPointF(50, 14), 8, 9)
        for seg, pts in BODY_SEGMENTS.items():
            label, health = self.segment_state.get(seg, ("", None))
            pen = QtGui.QPen(SYNC_QCOLOR.get(health, QtGui.QColor(120, 120, 120)), 6 if label else 2)
            pen.setCapStyle(QtCore.Qt.RoundCap)
            p.setPen(pen)
            p.drawLine(QtCore.QPointF(*pts[0]), QtCore.QPointF(*pts[1]))
        p.resetTransform()
        p.setPen(self.palette().color(QtGui.QPalette.WindowText))
        metrics = p.fontMetrics()
        for seg, (label, _) in self.segment_state.items():
            if not label or seg not in BODY_SEGMENTS:
                continue
            (x0, y0), (x1, y1) = BODY_SEGMENTS[seg]
            mid = figure.map(QtCore.QPointF((x0 + x1) / 2, (y0 + y1) / 2))
            width = metrics.horizontalAdvance(label)
            side = _label_side(seg)
            if side == "below":
                at = QtCore.QPointF(mid.x() - width / 2, mid.y() + 6 + metrics.ascent())
            else:
                at = QtCore.QPointF(mid.x() + 8 if side == "right" else mid.x() - 8 - width,
                                    mid.y() + metrics.ascent() / 2)
            p.drawText(at, label)
        p.end()


def _label_side(segment: str) -> str:
    """Where a segment's label goes: below a segment across the body (pelvis), right of the figure's left side
    (x > 50 is the viewer's right), left of its right side."""
    (x0, y0), (x1, y1) = BODY_SEGMENTS[segment]
    if abs(x1 - x0) > abs(y1 - y0):
        return "below"
    return "right" if (x0 + x1) / 2 >= 50 else "left"


def _fmt(value: Any, spec: str, scale: float = 1.0) -> str:
    return "–" if value is None else format(float(value) * scale, spec)


class DevicePanel(QtWidgets.QWidget):
    """Tree of stations -> sensors refreshed from each gateway status snapshot."""

    identify_requested = QtCore.Signal(str, int)  # station, sensor

    def __init__(self, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.tree = QtWidgets.QTreeWidget()
        self.tree.setColumnCount(len(COLUMNS))
        self.tree.setHeaderLabels(list(COLUMNS))
        self.tree.setRootIsDecorated(True)
        self.tree.setUniformRowHeights(True)
        self.tree.header().setStretchLastSection(False)  # the identify buttons keep their own width
        for col, tip in HEADER_TIPS.items():
            self.tree.headerItem().setToolTip(col, tip)
        self.bodies: dict[str, BodyDiagram] = {}  # athlete ("" for one) -> its diagram, created as athletes appear
        self.mapping: dict[tuple[str, int], str] = {}  # (station, sensor) -> diagram segment
        self.mapping_names: dict[tuple[str, int], str] = {}  # (station, sensor) -> placement name
        self._items: dict[Any, QtWidgets.QTreeWidgetItem] = {}
        self._new_rows = False
        self.sensor_health: dict[tuple[str, int], Sync] = {}  # last status: per-sensor health light
        self.commands_allowed = True  # False for a viewer connection: the gateway refuses station commands
        # who wears each sensor (the samples' ``athlete``; the console shares its bridge's dict): with several
        # athletes each station row names its athlete(s), so the panel reads per athlete (issue 20)
        self.sensor_athletes: dict[tuple[str, int], str] = {}
        layout = QtWidgets.QHBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addWidget(self.tree, 1)
        self._bodies_layout = QtWidgets.QHBoxLayout()
        layout.addLayout(self._bodies_layout)

    def set_mapping(self, mapping: dict[tuple[str, int], str]) -> None:
        """Sensor -> placement names (e.g. "left_forearm"); drawn on the diagram segment `segment_for` finds."""
        self.mapping_names = dict(mapping)
        self.mapping = {k: (segment_for(v) or v) for k, v in mapping.items()}

    def set_commands_allowed(self, allowed: bool) -> None:
        """Enable the per-sensor identify buttons only where the gateway would accept them (operator role)."""
        self.commands_allowed = allowed
        for item in self._items.values():
            button = self.tree.itemWidget(item, len(COLUMNS) - 1)
            if button is not None:
                self._allow(button)

    def _allow(self, button: QtWidgets.QPushButton) -> None:
        button.setEnabled(self.commands_allowed)
        button.setToolTip("" if self.commands_allowed else VIEWER_ONLY)

    def _item(self, key: Any, parent: QtWidgets.QTreeWidgetItem | None, label: str,
              sensor: tuple[str, int] | None = None) -> QtWidgets.QTreeWidgetItem:
        item = self._items.get(key)
        if item is None:
            item = QtWidgets.QTreeWidgetItem([label])
            (parent.addChild(item) if parent is not None else self.tree.addTopLevelItem(item))
            if sensor is not None:
                button = QtWidgets.QPushButton("identify")
                button.setSizePolicy(QtWidgets.QSizePolicy.Fixed, QtWidgets.QSizePolicy.Fixed)
                button.setToolTip("blink this sensor's LED")
                button.clicked.connect(lambda _=False, s=sensor: self.identify_requested.emit(*s))
                self._allow(button)
                self.tree.setItemWidget(item, len(COLUMNS) - 1, button)
            if parent is not None:
                parent.setExpanded(True)
            self._items[key] = item
            self._new_rows = True
        return item

    def update_status(self, status: dict[str, Any]) -> None:
        """Refresh every row from a status snapshot (docs/gateway.md); rows appear as devices do."""
        bodies: dict[str, dict[str, tuple[str, Sync]]] = {}
        self._drop_rows_not_in(status)
        for st in status.get("stations", []):
            sid = str(st.get("station"))
            clock = st.get("clock") or {}
            row = self._item(("station", sid), None, f"station {sid}")
            row.setText(0, self._station_label(sid))
            values = {1: str(st.get("link", "?")), 7: str(st.get("crc_errors", 0)),
                      8: _fmt(clock.get("offset_s"), "+.3f"), 9: _fmt(clock.get("skew_ppm"), ".1f"),
                      10: _fmt(clock.get("residual_s"), ".3f", 1e3)}
            for col, text in values.items():
                row.setText(col, text)
            row.setToolTip(8, OFFSET_TIP)
            self._show_sync(row, sync_status(st), sync_reason(st))
            for sensor in st.get("sensors", []):
                idx = int(sensor.get("sensor", 0))
                item = self._item(("sensor", sid, idx), row, f"sensor {idx}", (sid, idx))
                healthy, reason = sensor_sync(st, sensor)
                cols = {1: str(st.get("link", "?")), 2: _fmt(sensor.get("battery_pct"), ".0f"),
                        3: _fmt(sensor.get("rssi_dbm"), ".0f"),
                        4: f"{_fmt(sensor.get('rate_hz'), '.1f')} / {_fmt(sensor.get('nominal_hz'), '.0f')}",
                        5: _fmt(sensor.get("loss_pct"), ".2f"), 6: str(sensor.get("lost", 0)),
                        12: self.mapping_names.get((sid, idx), "")}
                for col, text in cols.items():
                    item.setText(col, text)
                self._show_sync(item, healthy, reason)
                self.sensor_health[(sid, idx)] = healthy
                seg = self.mapping.get((sid, idx), "")
                if seg:  # two sensors on one segment (forearm and wrist): both named, the worse health shown
                    body = bodies.setdefault(self.sensor_athletes.get((sid, idx), ""), {})
                    label, worst = body.get(seg, ("", Sync.GREEN))
                    body[seg] = (f"{label}, {sid}/{idx}" if label else f"{sid}/{idx}",
                                 max(worst, healthy, key=SYNC_RANK.index))
        self._show_bodies(bodies)
        if self._new_rows:
            for col in range(len(COLUMNS)):
                self.tree.resizeColumnToContents(col)
            self._new_rows = False

    @staticmethod
    def _show_sync(item: QtWidgets.QTreeWidgetItem, sync: Sync, reason: str) -> None:
        """The sync cell: its colour, the reason in a colour readable on it."""
        item.setText(11, reason)
        item.setBackground(11, SYNC_QCOLOR[sync])
        item.setForeground(11, QtGui.QColor(20, 20, 20) if sync is Sync.AMBER else QtGui.QColor(255, 255, 255))

    def _show_bodies(self, bodies: dict[str, dict[str, tuple[str, Sync]]]) -> None:
        """One diagram per athlete wearing mapped sensors (titled when there are several), in order seen."""
        titled = len(bodies) > 1
        for athlete, state in bodies.items():
            body = self.bodies.get(athlete)
            if body is None:
                body = self.bodies[athlete] = BodyDiagram()
                self._bodies_layout.addWidget(body)
            body.title = athlete if titled else ""
            body.set_state(state)

    @property
    def body(self) -> BodyDiagram | None:
        """The first athlete's diagram (one-athlete courts have only this one)."""
        return next(iter(self.bodies.values()), None)

    def _station_label(self, sid: str) -> str:
        """``station st1``, or ``station st1 · alice`` when several athletes wear the sensors."""
        athletes = dict(self.sensor_athletes)  # a snapshot: the network thread adds entries
        if len(set(athletes.values())) < 2:
            return f"station {sid}"
        who = sorted({name for (station, _), name in athletes.items() if station == sid})
        return f"station {sid}" + (f" · {', '.join(who)}" if who else "")

    def _drop_rows_not_in(self, status: dict[str, Any]) -> None:
        """Forget rows of stations the gateway no longer lists (a reader is named by its port until the first
        frame tells the station id, then it becomes ``st<id>``)."""
        present = {str(st.get("station")) for st in status.get("stations", [])}
        for key in [k for k in self._items if k[0] == "station" and k[1] not in present]:
            item = self._items.pop(key)
            self.tree.takeTopLevelItem(self.tree.indexOfTopLevelItem(item))
            for child in [k for k in self._items if k[0] == "sensor" and k[1] == key[1]]:
                self._items.pop(child)

    def identify_button(self, station: str, sensor: int) -> QtWidgets.QPushButton | None:
        item = self._items.get(("sensor", station, sensor))
        return None if item is None else self.tree.itemWidget(item, len(COLUMNS) - 1)

    def row_texts(self, key: Any) -> list[str]:
        """Texts of one row (("station", id) or ("sensor", id, idx)) — for tests."""
        item = self._items[key]
        return [item.text(c) for c in range(len(COLUMNS))]
