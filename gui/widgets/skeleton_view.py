"""3-D view pane: shows `gui.render.SkeletonRenderer` output in a plain QWidget.

The renderer draws offscreen (EGL) and hands back pixels; this widget only blits them, so it behaves the
same on a real display, Xvfb and the offscreen Qt platform. Drag to orbit, wheel to zoom, combo for
follow/static camera. Each athlete stands where the court says (`gui.render.placement`: its camera track, else
its half's default spot, named in the legend); the ground truth, when the take has one, beside the estimate, the
legend saying how far."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from PySide6 import QtCore, QtGui, QtWidgets

from gui.render.camera import CameraMode, OrbitCamera
from gui.render.placement import default_spot, place
from gui.render.skeleton_renderer import ESTIMATE_STYLE, TRUTH_STYLE, SkeletonRenderer, SkeletonStyle

TRUTH_BESIDE_M = 1.5  # ground truth drawn this far to the estimate's right on screen, not on top of it
# more athletes (issue 20): each in its own colour, at its own court spot
ESTIMATE_CSS = "#ff9a2a"
ATHLETE_STYLES = (SkeletonStyle(bone_rgb=(0.3, 0.85, 0.3), joint_rgb=(0.6, 1.0, 0.5)),
                  SkeletonStyle(bone_rgb=(0.85, 0.35, 0.85), joint_rgb=(1.0, 0.6, 1.0)))
ATHLETE_CSS = ("#4dd94d", "#d959d9")
# Render at most this many pixels and let Qt scale up: llvmpipe cost grows with the pixel count and the
# skeleton reads fine at 640x360 upscaled (a 1500x950 window otherwise costs ~2.5x more per frame).
MAX_RENDER_PIXELS = 640 * 360


def rgba_to_qimage(pixels: np.ndarray) -> QtGui.QImage:
    """Copy (H, W, 4) uint8 RGBA into a QImage that owns its memory.

    Why copy into ``bits()`` instead of wrapping the numpy buffer: a QImage constructed over a Python buffer
    must keep that buffer alive for its whole life, and doing so through PySide6's buffer constructor has
    corrupted reference counts here (interpreter abort under load)."""
    h, w = pixels.shape[:2]
    image = QtGui.QImage(w, h, QtGui.QImage.Format_RGBA8888)
    dst = np.frombuffer(image.bits(), np.uint8).reshape(h, image.bytesPerLine())
    dst[:, :4 * w] = pixels.reshape(h, 4 * w)
    return image


LOW_CONFIDENCE_RGB = (0.45, 0.45, 0.45)


def confidence_style(style: SkeletonStyle, confidence: float) -> SkeletonStyle:
    """``style`` with bones and joints blended towards grey by (1 - confidence)."""
    mix = lambda rgb: tuple(confidence * c + (1 - confidence) * g for c, g in zip(rgb, LOW_CONFIDENCE_RGB))  # noqa: E731
    return replace(style, bone_rgb=mix(style.bone_rgb), joint_rgb=mix(style.joint_rgb))


class SkeletonView(QtWidgets.QWidget):
    def __init__(self, renderer: SkeletonRenderer | None = None, parent: QtWidgets.QWidget | None = None) -> None:
        super().__init__(parent)
        # no MSAA by default: on Mesa llvmpipe 4x MSAA triples the frame cost (14 ms vs 4 ms at 820x420)
        self.renderer = renderer or SkeletonRenderer(640, 360, samples=0)
        self.camera = OrbitCamera()
        self.parents: np.ndarray | None = None
        self.estimate_m: np.ndarray | None = None
        self.truth_m: np.ndarray | None = None
        self.estimate_style = ESTIMATE_STYLE
        self.confidence_level: float | None = None
        self.athlete: str | None = None  # the estimate's athlete (named in the legend when there are several)
        self.others: dict[str, tuple[np.ndarray, SkeletonStyle]] = {}  # more athletes: name -> (pose, style)
        self.sides: dict[str, str | None] = {}  # athlete -> "near" / "far" (the gateway's hello), for default spots
        self.court_spots: dict[str, np.ndarray] = {}  # athlete -> court (x, y) from its camera track, when it has one
        self._image: QtGui.QImage | None = None
        self._pixels: np.ndarray | None = None
        self._dirty = True
        self._snapped = False
        self._drag: QtCore.QPointF | None = None
        self.frames_rendered = 0
        self.setMinimumSize(320, 200)
        self.mode_box = QtWidgets.QComboBox(self)
        for mode in CameraMode:
            self.mode_box.addItem(mode.value, mode)
        self.mode_box.currentIndexChanged.connect(lambda _: self.set_camera_mode(self.mode_box.currentData()))
        self.mode_box.move(6, 6)
        self.legend = QtWidgets.QLabel(self)
        self.legend.setStyleSheet("color:#ddd; background:transparent;")
        self.legend.move(110, 9)

    # -- data --------------------------------------------------------------------------------------------------
    def set_skeleton(self, parents: np.ndarray) -> None:
        self.parents = np.asarray(parents)
        self._dirty = True

    def set_poses(self, estimate_m: np.ndarray | None, truth_m: np.ndarray | None = None) -> None:
        """Joint positions (J,3) m, world frame. Either may be None (not available yet)."""
        self.estimate_m = None if estimate_m is None else np.asarray(estimate_m, float)
        self.truth_m = None if truth_m is None else np.asarray(truth_m, float)
        self._update_legend()
        self._dirty = True

    def set_other_athletes(self, poses: dict[str, tuple[np.ndarray | None, float | None]]) -> None:
        """Poses (J,3) m and confidence (None = not reported) of the athletes after the first, in order; a None
        pose keeps that athlete's last one."""
        for k, (name, (pose, confidence)) in enumerate(poses.items()):
            if pose is None:
                continue
            style = ATHLETE_STYLES[k % len(ATHLETE_STYLES)]
            if confidence is not None and np.isfinite(confidence):
                style = confidence_style(style, round(float(np.clip(confidence, 0, 1)), 1))
            self._snapped = self._snapped and name in self.others  # an athlete appears: frame them all at once
            self.others[name] = (np.asarray(pose, float), style)
        self._update_legend()
        self._dirty = True

    def set_court_spots(self, spots: dict[str, np.ndarray | None]) -> None:
        """Each athlete's court (x, y) m from its camera track (None: no track, its default spot is used)."""
        spots = {name: np.asarray(xy, float) for name, xy in spots.items() if xy is not None}
        if spots.keys() == self.court_spots.keys() and all(np.array_equal(xy, self.court_spots[name])
                                                           for name, xy in spots.items()):
            return  # unchanged: no re-render (a console without synthesis calls this every tick)
        self.court_spots = spots
        self._update_legend()
        self._dirty = True

    def athlete_colours(self, names: list[str]) -> dict[str, str]:
        """CSS colour of each athlete's skeleton, first athlete first (for the per-athlete status)."""
        return {name: ESTIMATE_CSS if k == 0 else ATHLETE_CSS[(k - 1) % len(ATHLETE_CSS)]
                for k, name in enumerate(names)}

    def _first_name(self) -> str:
        return self.athlete or ""

    def _spot(self, name: str, index: int) -> np.ndarray:
        spot = self.court_spots.get(name)
        return spot if spot is not None else default_spot(self.sides.get(name), index)

    def _where(self, name: str, index: int) -> str:
        """The legend's note on an athlete drawn without a camera track."""
        if name in self.court_spots:
            return ""
        side = self.sides.get(name) or ("far" if index % 2 else "near")
        return f" (no camera: at the {side} baseline)"

    def _update_legend(self) -> None:
        first = self._first_name()
        name = f" {self.athlete}" if self.athlete and self.others else ""
        text = (f"<span style='color:{ESTIMATE_CSS}'>■ estimate{name}{self._where(first, 0)}</span>  "
                if self.estimate_m is not None else "")
        text += "".join(f"<span style='color:{ATHLETE_CSS[k % len(ATHLETE_CSS)]}'>■ {other}"
                        f"{self._where(other, k + 1)}</span>  " for k, other in enumerate(self.others))
        if self.truth_m is not None:
            beside = f" (drawn {TRUTH_BESIDE_M:g} m beside the estimate)" if self.estimate_m is not None else ""
            text += f"<span style='color:#4fd8e6'>■ ground truth{beside}</span>"
        self.legend.setText(text)
        self.legend.adjustSize()

    def set_segment_colours(self, segment_rgb: dict[int, tuple[float, float, float]]) -> None:
        """Paint the estimate's segments (joint index -> RGB), e.g. sensors in trouble; {} = normal colours."""
        if segment_rgb != (self.estimate_style.segment_rgb or {}):
            self.estimate_style = replace(self.estimate_style, segment_rgb=dict(segment_rgb) or None)
            self._dirty = True

    def set_confidence(self, confidence: float | None) -> None:
        """Tint the estimate by the engine's confidence in this frame: full colour at 1, fading to grey at 0
        (None: the engine reports none, normal colours). Quantised to 10 steps so it does not re-render for
        every small change."""
        level = None if confidence is None or not np.isfinite(confidence) else round(float(np.clip(confidence, 0, 1)), 1)
        if level == self.confidence_level:
            return
        self.confidence_level = level
        base = ESTIMATE_STYLE if level is None else confidence_style(ESTIMATE_STYLE, level)
        self.estimate_style = replace(base, segment_rgb=self.estimate_style.segment_rgb)
        self._dirty = True

    def set_camera_mode(self, mode: CameraMode) -> None:
        self.camera.set_mode(mode)
        self._snapped = False
        self._dirty = True
        if self.mode_box.currentData() != mode:
            self.mode_box.setCurrentIndex(list(CameraMode).index(CameraMode(mode)))

    # -- rendering ---------------------------------------------------------------------------------------------
    def pending(self) -> bool:
        """A render is waiting (something changed and the view is on screen): the refresh tick schedules it."""
        return self._dirty and self.isVisible()

    def refresh(self) -> bool:
        """Render if anything changed (GUI thread, from the refresh tick). Returns True if a frame was drawn."""
        if not self.pending():
            return False
        w, h = self.width() * self.devicePixelRatioF(), self.height() * self.devicePixelRatioF()
        scale = min(1.0, (MAX_RENDER_PIXELS / max(1.0, w * h)) ** 0.5)
        self.renderer.resize(int(w * scale), int(h * scale))
        skeletons = self._placed_skeletons()
        # the athletes' roots frame the view (a truth beside the estimate is in view with it; alone, it frames)
        framing = [pose[0] for pose, _, style in skeletons if style is not TRUTH_STYLE or len(skeletons) == 1]
        roots = np.array(framing) if framing else None
        aspect = self.renderer.size[0] / self.renderer.size[1]
        if roots is not None and not self._snapped:
            self.camera.snap_to(roots, aspect)
            self._snapped = True
        self.camera.follow(roots, aspect)
        self._pixels = np.ascontiguousarray(self.renderer.render(self.camera, skeletons))
        h, w = self._pixels.shape[:2]
        self._image = rgba_to_qimage(self._pixels)
        self._dirty = False
        self.frames_rendered += 1
        self.update()
        return True

    def _placed_skeletons(self) -> list[tuple[np.ndarray, np.ndarray, SkeletonStyle]]:
        """(joints, parents, style) of every figure to draw, each athlete over its court spot (module doc), the
        truth beside the estimate (or on the first athlete's spot when there is no estimate)."""
        if self.parents is None:
            return []
        skeletons = []
        first = self._spot(self._first_name(), 0)
        if self.estimate_m is not None:
            skeletons.append((place(self.estimate_m, first), self.parents, self.estimate_style))
        if self.truth_m is not None:
            offset = TRUTH_BESIDE_M * self.camera.right_m() if self.estimate_m is not None else 0.0
            skeletons.append((place(self.truth_m, first) + offset, self.parents, TRUTH_STYLE))
        for k, (name, (pose, style)) in enumerate(self.others.items(), 1):
            skeletons.append((place(pose, self._spot(name, k)), self.parents, style))
        return skeletons

    def last_pixels(self) -> np.ndarray | None:
        """The last rendered RGBA frame (H, W, 4), row 0 at the top."""
        return self._pixels

    def paintEvent(self, _event: QtGui.QPaintEvent) -> None:
        p = QtGui.QPainter(self)
        if self._image is not None:
            p.setRenderHint(QtGui.QPainter.SmoothPixmapTransform)
            p.drawImage(QtCore.QRectF(self.rect()), self._image)
        else:
            p.fillRect(self.rect(), QtGui.QColor(28, 30, 36))
        p.end()

    def resizeEvent(self, event: QtGui.QResizeEvent) -> None:
        self._dirty = True
        super().resizeEvent(event)

    def showEvent(self, event: QtGui.QShowEvent) -> None:
        self._dirty = True
        super().showEvent(event)

    # -- interaction -------------------------------------------------------------------------------------------
    def mousePressEvent(self, event: QtGui.QMouseEvent) -> None:
        self._drag = event.position()

    def mouseMoveEvent(self, event: QtGui.QMouseEvent) -> None:
        if self._drag is None:
            return
        d = event.position() - self._drag
        self._drag = event.position()
        self.camera.orbit(math.radians(-0.4 * d.x()), math.radians(0.3 * d.y()))
        self._dirty = True

    def mouseReleaseEvent(self, _event: QtGui.QMouseEvent) -> None:
        self._drag = None

    def wheelEvent(self, event: QtGui.QWheelEvent) -> None:
        self.camera.zoom(0.9 if event.angleDelta().y() > 0 else 1.0 / 0.9)
        self._dirty = True
