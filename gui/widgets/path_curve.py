"""A bare polyline item for pyqtgraph plots whose view ranges are set by hand (the live traces).

Why not `pg.PlotCurveItem`: on every `setData` it invalidates and re-scans its data bounds (nanmin / nanmax per
axis), and the scene asks its `boundingRect` several times per paint, each time through Python; with 24 curves
redrawn 30 times a second that was the largest single cost of a trace redraw (profiled: ~40 % of the curves'
time). Here the path is built once per `setData` (`pg.arrayToQPath`, vectorised) and its bounds come from Qt
(`QPainterPath.controlPointRect`, C++)."""
from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6 import QtCore, QtGui, QtWidgets


class PathCurve(pg.GraphicsObject):
    """One pen, one connected polyline; `xData` / `yData` are what was last drawn (finite values only)."""

    def __init__(self, pen: QtGui.QPen) -> None:
        super().__init__()
        self.pen = pen
        self.pen.setCosmetic(True)  # one pixel wide whatever the view's scale
        self.xData = np.zeros(0)
        self.yData = np.zeros(0)
        self._path = QtGui.QPainterPath()
        self._bounds = QtCore.QRectF()

    def setData(self, x: np.ndarray, y: np.ndarray) -> None:
        """Replace the polyline by (x, y) (same length, finite)."""
        self.xData, self.yData = np.asarray(x, float), np.asarray(y, float)
        self.prepareGeometryChange()
        self._path = pg.arrayToQPath(self.xData, self.yData, connect="all") if len(self.xData) > 1 \
            else QtGui.QPainterPath()
        # padded: a flat line's zero-height rect would count as empty and be culled
        self._bounds = self._path.controlPointRect().adjusted(-1e-6, -1e-6, 1e-6, 1e-6)
        self.update()

    def boundingRect(self) -> QtCore.QRectF:
        return self._bounds

    def paint(self, painter: QtGui.QPainter, _option: QtWidgets.QStyleOptionGraphicsItem,
              _widget: QtWidgets.QWidget | None = None) -> None:
        painter.setPen(self.pen)
        painter.drawPath(self._path)
