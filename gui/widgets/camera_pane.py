"""Camera pane: the latest overhead frame with the court model and detected player overlaid, and a court
minimap with the player's recent trail and heading.

Overlay geometry comes from the camera message header (docs/gateway.md ``camera``): ``position_m`` (court
x, y), ``heading_rad``, and, when the gateway sends it, ``court_to_image`` (3x3 ground homography, court metres
-> frame pixels) plus optional ``bbox_px`` [x0, y0, x1, y1] of the detected blob. Without the homography only
the frame and the minimap are shown (the overlay cannot be placed honestly)."""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from PySide6 import QtCore, QtGui, QtWidgets

from gui.bridge import CameraRate
from gui.render.court import COURT_LENGTH_M, DOUBLES_WIDTH_M, court_line_segments

LINE_PEN = QtGui.QColor(240, 240, 240)
PLAYER_COLOUR = QtGui.QColor(255, 140, 20)
# more athletes (issue 20): the same colours as their skeletons in the 3-D view (gui.widgets.skeleton_view)
OTHER_COLOURS = (QtGui.QColor(77, 217, 77), QtGui.QColor(217, 89, 217))


def apply_homography(h: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N,2) points through a 3x3 homography (vectorised, with the perspective divide)."""
    p = np.c_[np.asarray(points, float), np.ones(len(points))] @ np.asarray(h, float).T
    return p[:, :2] / p[:, 2:3]


class CameraView(QtWidgets.QWidget):
    """Frame + overlay, letterboxed to the widget."""

    def __init__(self, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.image: QtGui.QImage | None = None
        self._jpeg: bytes | None = None
        self.header: dict[str, Any] = {}
        self.others: list[tuple[dict[str, Any], QtGui.QColor]] = []  # more athletes' observations, colours
        self.setMinimumSize(240, 160)

    def set_frame(self, header: dict[str, Any] | None, jpeg: bytes | None) -> None:
        if jpeg and jpeg is not self._jpeg:
            self._jpeg = jpeg
            img = QtGui.QImage.fromData(jpeg)
            if not img.isNull():
                self.image = img
        self.header = header or {}
        self.update()

    def _image_rect(self) -> QtCore.QRectF:
        if self.image is None:
            return QtCore.QRectF(self.rect())
        s = min(self.width() / self.image.width(), self.height() / self.image.height())
        w, h = self.image.width() * s, self.image.height() * s
        return QtCore.QRectF((self.width() - w) / 2, (self.height() - h) / 2, w, h)

    def paintEvent(self, _event: QtGui.QPaintEvent) -> None:
        p = QtGui.QPainter(self)
        p.fillRect(self.rect(), QtGui.QColor(25, 25, 28))
        if self.image is None:
            p.setPen(QtGui.QColor(160, 160, 160))
            p.drawText(self.rect(), QtCore.Qt.AlignCenter, "no camera frames")
            p.end()
            return
        target = self._image_rect()
        p.drawImage(target, self.image)
        p.setRenderHint(QtGui.QPainter.Antialiasing)
        sx = target.width() / self.image.width()
        p.translate(target.topLeft())
        p.scale(sx, sx)
        h = self.header.get("court_to_image")
        if h is not None:
            h = np.asarray(h, float).reshape(3, 3)
            p.setPen(QtGui.QPen(QtGui.QColor(60, 230, 255), 1.5 / sx))
            segs = court_line_segments()
            ends = apply_homography(h, segs.reshape(-1, 2)).reshape(-1, 2, 2)
            for (x0, y0), (x1, y1) in ends:
                p.drawLine(QtCore.QPointF(x0, y0), QtCore.QPointF(x1, y1))
            for header, colour in [(self.header, PLAYER_COLOUR), *self.others]:
                pos = header.get("position_m")
                if pos is not None:
                    (fx, fy), = apply_homography(h, np.array([pos[:2]]))
                    p.setPen(QtGui.QPen(colour, 2.5 / sx))
                    p.drawEllipse(QtCore.QPointF(fx, fy), 6 / sx, 6 / sx)
                    p.drawLine(QtCore.QPointF(fx - 10 / sx, fy), QtCore.QPointF(fx + 10 / sx, fy))
                    p.drawLine(QtCore.QPointF(fx, fy - 10 / sx), QtCore.QPointF(fx, fy + 10 / sx))
        for header, colour in [(self.header, PLAYER_COLOUR), *self.others]:
            bbox = header.get("bbox_px")
            if bbox is not None:
                p.setPen(QtGui.QPen(colour, 1.5 / sx))
                p.drawRect(QtCore.QRectF(bbox[0], bbox[1], bbox[2] - bbox[0], bbox[3] - bbox[1]))
        p.end()


class CourtMinimap(QtWidgets.QWidget):
    """Top view of the court (x across, far baseline up) with the trail and current position + heading."""

    MARGIN_M = 3.0

    def __init__(self, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.trail_m = np.zeros((0, 2))
        self.position_m: np.ndarray | None = None
        self.heading_rad: float | None = None
        self.others: list[tuple[np.ndarray, Any, float | None, QtGui.QColor]] = []  # (trail, pos, heading, colour)
        self.setMinimumSize(120, 200)

    def set_track(self, trail_m: np.ndarray, position_m: Any, heading_rad: float | None) -> None:
        self.trail_m = np.asarray(trail_m, float).reshape(-1, 2)
        self.position_m = None if position_m is None else np.asarray(position_m, float)[:2]
        self.heading_rad = heading_rad
        self.update()

    def court_to_widget(self) -> QtGui.QTransform:
        """Court metres -> widget pixels (far baseline at the top): shared with tests."""
        w_m, h_m = DOUBLES_WIDTH_M + 2 * self.MARGIN_M, COURT_LENGTH_M + 2 * self.MARGIN_M
        s = min(self.width() / w_m, self.height() / h_m)
        t = QtGui.QTransform()
        t.translate(self.width() / 2, self.height() / 2)
        t.scale(s, -s)
        return t

    def paintEvent(self, _event: QtGui.QPaintEvent) -> None:
        p = QtGui.QPainter(self)
        p.fillRect(self.rect(), QtGui.QColor(30, 70, 55))
        p.setRenderHint(QtGui.QPainter.Antialiasing)
        p.setTransform(self.court_to_widget())
        p.fillRect(QtCore.QRectF(-DOUBLES_WIDTH_M / 2, -COURT_LENGTH_M / 2, DOUBLES_WIDTH_M, COURT_LENGTH_M),
                   QtGui.QColor(40, 85, 140))
        pen = QtGui.QPen(LINE_PEN)
        pen.setCosmetic(True)
        p.setPen(pen)
        for (x0, y0), (x1, y1) in court_line_segments():
            p.drawLine(QtCore.QPointF(x0, y0), QtCore.QPointF(x1, y1))
        p.drawLine(QtCore.QPointF(-DOUBLES_WIDTH_M / 2 - 0.9, 0), QtCore.QPointF(DOUBLES_WIDTH_M / 2 + 0.9, 0))
        tracks = [(self.trail_m, self.position_m, self.heading_rad, PLAYER_COLOUR), *self.others]
        for trail_m, position_m, heading_rad, colour in tracks:
            self._draw_track(p, trail_m, position_m, heading_rad, colour)
        p.end()

    @staticmethod
    def _draw_track(p: QtGui.QPainter, trail_m: np.ndarray, position_m: Any, heading_rad: float | None,
                    colour: QtGui.QColor) -> None:
        if len(trail_m) > 1:
            faded = QtGui.QColor(colour)
            faded.setAlpha(160)
            trail_pen = QtGui.QPen(faded.lighter(130), 2)
            trail_pen.setCosmetic(True)
            p.setPen(trail_pen)
            p.drawPolyline(QtGui.QPolygonF([QtCore.QPointF(x, y) for x, y in trail_m]))
        if position_m is not None:
            x, y = np.asarray(position_m, float)[:2]
            p.setPen(QtCore.Qt.NoPen)
            p.setBrush(colour)
            p.drawEllipse(QtCore.QPointF(x, y), 0.35, 0.35)
            if heading_rad is not None:
                # heading 0 faces +y (towards the far baseline), positive counter-clockwise seen from above
                hx, hy = -math.sin(heading_rad), math.cos(heading_rad)
                arrow = QtGui.QPen(colour, 2)
                arrow.setCosmetic(True)
                p.setPen(arrow)
                p.drawLine(QtCore.QPointF(x, y), QtCore.QPointF(x + 1.2 * hx, y + 1.2 * hy))


class CameraPane(QtWidgets.QWidget):
    def __init__(self, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        self.view = CameraView()
        self.minimap = CourtMinimap()
        self.info = QtWidgets.QLabel("camera: –")
        self.athletes_info = QtWidgets.QLabel("")
        self._last_header: dict[str, Any] | None = None
        self._last_jpeg: bytes | None = None
        right = QtWidgets.QVBoxLayout()
        right.addWidget(self.minimap, 1)
        right.addWidget(self.info)
        right.addWidget(self.athletes_info)
        layout = QtWidgets.QHBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addWidget(self.view, 3)
        layout.addLayout(right, 1)

    def update_camera(self, header: dict[str, Any] | None, jpeg: bytes | None, trail: np.ndarray,
                      stats: CameraRate) -> None:
        """trail: (N, 3) [t_s, x_m, y_m] as kept by `gui.bridge.GatewayBridge`. Called every tick; does nothing
        unless a new observation arrived (the bridge stores a new header object per camera message)."""
        if header is self._last_header and jpeg is self._last_jpeg:
            return
        self._last_header, self._last_jpeg = header, jpeg
        self.view.set_frame(header, jpeg)
        header = header or {}
        self.minimap.set_track(trail[:, 1:3], header.get("position_m"), header.get("heading_rad"))
        if header:
            pos = header.get("position_m") or [float("nan")] * 2
            state = "" if header.get("tracking", True) else "  NOT TRACKING"
            self.info.setText(f"t {header.get('t_host_s', 0):.2f} s  pos ({pos[0]:+.2f}, {pos[1]:+.2f}) m  "
                              f"conf {float(header.get('confidence', float('nan'))):.2f}{state}\n"
                              f"camera {stats.fps:.1f} fps, {stats.dropped} dropped")

    def update_athletes(self, tracks: dict[str, tuple[dict[str, Any], np.ndarray]], first: str | None) -> None:
        """The other athletes' newest observations and trails (`gui.bridge.GatewayBridge.athlete_tracks`), in
        their own colours on the overlay and the minimap; ``first`` is the athlete `update_camera` shows.
        One athlete: nothing to add (no repaint)."""
        others = [(header, trail) for name, (header, trail) in tracks.items() if name != first]
        if not others:
            return
        colours = [OTHER_COLOURS[k % len(OTHER_COLOURS)] for k in range(len(others))]
        self.view.others = [(header, colour) for (header, _), colour in zip(others, colours)]
        self.minimap.others = [(trail[:, 1:3], header.get("position_m"), header.get("heading_rad"), colour)
                               for (header, trail), colour in zip(others, colours)]
        lines = []
        for name, (header, _) in tracks.items():
            pos = header.get("position_m")
            lines.append(f"{name}: " + (f"({pos[0]:+.1f}, {pos[1]:+.1f}) m" if pos is not None
                                        else str(header.get("status", "not tracking")).upper()))
        self.athletes_info.setText("  ".join(lines))
        self.view.update()
        self.minimap.update()
