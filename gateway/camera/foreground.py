"""Court foreground detection shared by every player track: frozen background model -> blobs -> ground points.

Why one detector for all tracks: the background model, the gain estimate and the blob extraction are per frame,
not per player; with two athletes on court they must run once and their blobs be *assigned* to tracks
(:mod:`gateway.camera.tracker`), or each track would pay for a full background subtraction of the same image.
Design notes (MOG2 frozen after warm-up, gain matching, learning around the players, the two ground-point
methods) are in :mod:`gateway.camera.tracker`'s docstring.

Detection runs at ``1 / detect_downscale`` of the camera's resolution (block average, ``cv2.INTER_AREA``): the
background model costs per pixel and a player is hundreds of pixels tall, so half resolution quarters the work
(the gateway's camera was most of its CPU on the board) and the averaged pixels are less noisy. Everything this
module returns -- blob pixels, centroids, areas, boxes -- is in *full-resolution* pixels again, so the ground
point, the lag check and the records keep one meaning whatever the downscale.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from gateway.camera.court import court_outline_m
from gateway.camera.court_calibration import CourtCalibration

if TYPE_CHECKING:  # the config lives with the tracker; imported for annotations only (no import cycle)
    from gateway.camera.tracker import TrackerConfig


@dataclass(frozen=True)
class Blob:
    """A foreground component in full-resolution pixels: ``pixels_xy`` (N, 2) x, y are the centres of the mask
    pixels it covers, each ``pixel_size_px`` full-resolution pixels wide (the detection downscale)."""

    centroid_px: np.ndarray
    area_px: float
    pixels_xy: np.ndarray
    pixel_size_px: float = 1.0

    def bbox_px(self) -> tuple[float, float, float, float]:
        """``(x0, y0, x1, y1)`` full-resolution pixel box, exclusive end."""
        half = self.pixel_size_px / 2.0
        (x0, y0), (x1, y1) = self.pixels_xy.min(axis=0) - half + 0.5, self.pixels_xy.max(axis=0) + half + 0.5
        return float(x0), float(y0), float(x1), float(y1)


class CourtForeground:
    """Background subtraction restricted to the court, blob extraction and the ground point under a blob."""

    def __init__(self, calibration: CourtCalibration, config: "TrackerConfig") -> None:
        if config.ground_point not in ("foot", "centroid", "auto"):
            raise ValueError(f"ground_point must be 'foot', 'centroid' or 'auto', got {config.ground_point!r}")
        if config.ground_point == "centroid" and not calibration.has_pose:
            raise ValueError("ground_point='centroid' needs a court calibration fitted with camera intrinsics")
        if config.detect_downscale < 1:
            raise ValueError(f"detect_downscale must be >= 1, got {config.detect_downscale}")
        self.calibration = calibration
        self.config = config
        #: The ground-point method in use ("auto" resolved): the parallax-corrected centroid when the pose is known.
        self.ground_point = config.ground_point
        if self.ground_point == "auto":
            self.ground_point = "centroid" if calibration.has_pose else "foot"
        self._camera_m = calibration.camera_position_m() if self.ground_point == "centroid" else None
        #: Side of one detection (mask) pixel in full-resolution pixels.
        self.downscale = config.detect_downscale
        width, height = calibration.image_size
        self._mask_size = (width // self.downscale, height // self.downscale)
        # var_threshold is the full-resolution setting. Block averages are less noisy (pixel variance 7 -> 3.3 DN^2
        # on the synthetic court, under MOG2's variance floor of 4), so an unchanged threshold would flag smaller
        # contrasts than at full resolution; sqrt(downscale) keeps it nearer the old absolute contrast. Measured at
        # half resolution against x1 and x2: x1 slightly worse on position and lag, x2 within 4 mm on position but
        # a larger lag error (docs/camera-calibration.md).
        self._mog = cv2.createBackgroundSubtractorMOG2(config.history, config.var_threshold * self.downscale**0.5,
                                                       detectShadows=True)
        self._mog.setNMixtures(config.mixtures)
        self._roi = np.zeros(self._mask_size[::-1], np.uint8)
        outline = self.to_mask_px(calibration.court_to_image(court_outline_m(config.court_margin_m)))
        cv2.fillConvexPoly(self._roi, np.round(outline).astype(np.int32), 255)
        # sparse court pixels for the gain estimate (~1300 at half resolution: the median's error is ~0.05 %,
        # well inside the 0.3 % dead band of _compensate_gain)
        self._gain_samples = np.flatnonzero(self._roi.ravel())[::37]
        self._background: np.ndarray | None = None
        self._background_level = 0.0
        # open 3x3 / close 7x7 full-resolution pixels, scaled: at half resolution the 3x3 opening would erase
        # thin arms and legs in some frames, and the centroid's jitter would drown the IMU-camera lag check
        self._open = _ellipse(3 / self.downscale)
        self._close = _ellipse(7 / self.downscale)
        self._last_detected: np.ndarray | None = None  # the last frame detected on, gain-matched (learn_around)
        self.frames_seen = 0
        self._updates_due = 0

    @property
    def warmed_up(self) -> bool:
        return self.frames_seen >= self.config.warmup_frames

    def to_full_px(self, mask_xy: np.ndarray) -> np.ndarray:
        """Mask pixel coordinates -> full-resolution pixel coordinates (a mask pixel's centre is the centre of the
        ``downscale`` x ``downscale`` block it averages)."""
        return mask_xy * self.downscale + (self.downscale - 1) / 2.0

    def to_mask_px(self, full_xy: np.ndarray) -> np.ndarray:
        """Full-resolution pixel coordinates -> mask pixel coordinates (inverse of :meth:`to_full_px`)."""
        return (full_xy - (self.downscale - 1) / 2.0) / self.downscale

    def mask_area_px(self, mask: np.ndarray) -> int:
        """Foreground area of a mask from :meth:`foreground`, in full-resolution pixels."""
        return int(cv2.countNonZero(mask)) * self.downscale**2

    def _detection_image(self, image: np.ndarray) -> np.ndarray:
        """The frame at detection resolution: ``downscale`` x ``downscale`` block averages (rows and columns past
        the last whole block dropped, so the scale is exact)."""
        if self.downscale == 1:
            return image
        w, h = self._mask_size
        return cv2.resize(image[: h * self.downscale, : w * self.downscale], (w, h), interpolation=cv2.INTER_AREA)

    def _compensate_gain(self, image: np.ndarray) -> np.ndarray:
        """Scale the frame so its court brightness matches the background model's (median ratio over a sparse
        grid of court pixels: the players cover too few of them to move the median). Global lighting changes
        (a cloud, flicker) then never reach the background subtractor."""
        if self._background is None:
            return image
        ratio = self._background_level / max(self._court_level(image), 1.0)
        return image if abs(ratio - 1.0) < 0.003 else cv2.convertScaleAbs(image, alpha=ratio)

    def _refresh_background(self) -> None:
        self._background = self._mog.getBackgroundImage()
        self._background_level = self._court_level(self._background)

    def _court_level(self, image: np.ndarray) -> float:
        """Median over the gain samples of B + G + R."""
        return float(np.median(image.reshape(-1, 3)[self._gain_samples].sum(axis=1)))

    def foreground(self, image: np.ndarray) -> np.ndarray:
        """Cleaned foreground mask (uint8 0/255, detection resolution) of one full-resolution frame; updates the
        background only during warm-up."""
        small = self._detection_image(image)
        if not self.warmed_up:
            raw = self._mog.apply(small, learningRate=-1.0)
        else:
            if self._background is None:
                self._refresh_background()
            self._last_detected = self._compensate_gain(small)
            raw = self._mog.apply(self._last_detected, learningRate=0.0)
        self.frames_seen += 1
        mask = cv2.bitwise_and(cv2.threshold(raw, 254, 255, cv2.THRESH_BINARY)[1], self._roi)  # shadows (127) out
        if self._open is not None:
            mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, self._open)
        return cv2.morphologyEx(mask, cv2.MORPH_CLOSE, self._close)

    def blobs(self, mask: np.ndarray) -> list[Blob]:
        """Connected components of a :meth:`foreground` mask above ``min_area_px`` (full-resolution pixels),
        largest first."""
        # Grana's algorithm: same components, 2.7x faster with statistics than OpenCV 5.1's default (Spaghetti)
        n, labels, stats, centroids = cv2.connectedComponentsWithStatsWithAlgorithm(mask, 8, cv2.CV_32S,
                                                                                    cv2.CCL_GRANA)
        areas = stats[:, cv2.CC_STAT_AREA] * self.downscale**2
        order = [i for i in np.argsort(-areas[1:]) + 1 if areas[i] >= self.config.min_area_px]
        out = []
        for i in order:
            x, y, w, h = stats[i, :4]
            ys, xs = np.nonzero(labels[y : y + h, x : x + w] == i)
            pixels = self.to_full_px(np.column_stack([xs + x, ys + y]).astype(float))
            out.append(Blob(self.to_full_px(centroids[i].astype(float)), float(areas[i]), pixels, self.downscale))
        return out

    def ground_point_m(self, blob: Blob) -> np.ndarray:
        """Court position (2,) m of the player's ground contact under this blob (see the tracker's docstring)."""
        camera = self._camera_m
        if camera is not None:
            hit = self.calibration.image_to_court(blob.centroid_px[None])[0]
            return camera[:2] + (hit - camera[:2]) * (1.0 - self.config.centroid_height_m / camera[2])
        down = self.calibration.image_down_directions(blob.centroid_px[None])[0]
        along = (blob.pixels_xy - blob.centroid_px) @ down
        foot_px = blob.centroid_px + down * np.percentile(along, self.config.foot_percentile)
        return self.calibration.image_to_court(foot_px[None])[0]

    def learn_around(self, players: Sequence[Blob]) -> None:
        """Background update that cannot learn the players: the last frame given to :meth:`foreground`, with their
        (grown) boxes replaced by the background. Called once per frame while at least one player is tracked;
        learns every ``background_update_every``."""
        cfg = self.config
        self._updates_due += 1
        if not cfg.background_update_every or self._updates_due < cfg.background_update_every:
            return
        self._updates_due = 0
        background = self._background
        if background is None or self._last_detected is None:
            return
        composite = self._last_detected.copy()
        m = cfg.background_update_margin_px
        for player in players:
            x0, y0, x1, y1 = player.bbox_px()
            x0, y0 = (max(int(v - m) // self.downscale, 0) for v in (x0, y0))
            x1, y1 = (-(-int(v + m) // self.downscale) for v in (x1, y1))  # ceil: the box grows, never shrinks
            composite[y0:y1, x0:x1] = background[y0:y1, x0:x1]
        self._mog.apply(composite, learningRate=cfg.background_learning_rate)
        self._refresh_background()


def _ellipse(size_px: float) -> np.ndarray | None:
    """Elliptic structuring element of the odd size nearest ``size_px`` (odd: centred, so opening and closing do
    not shift the mask); None when that is a single pixel (a no-op)."""
    size = 2 * round((size_px - 1) / 2) + 1
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size)) if size > 1 else None
