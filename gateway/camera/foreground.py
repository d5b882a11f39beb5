"""Court foreground detection shared by every player track: frozen background model -> blobs -> ground points.

Why one detector for all tracks: the background model, the gain estimate and the blob extraction are per frame,
not per player; with two athletes on court they must run once and their blobs be *assigned* to tracks
(:mod:`gateway.camera.tracker`), or each track would pay for a full background subtraction of the same image.
Design notes (MOG2 frozen after warm-up, gain matching, learning around the players, the two ground-point
methods) are in :mod:`gateway.camera.tracker`'s docstring.
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
    centroid_px: np.ndarray
    area_px: float
    pixels_xy: np.ndarray  # (N, 2) x, y

    def bbox_px(self) -> tuple[float, float, float, float]:
        """``(x0, y0, x1, y1)`` pixel box, exclusive end."""
        (x0, y0), (x1, y1) = self.pixels_xy.min(axis=0), self.pixels_xy.max(axis=0) + 1
        return float(x0), float(y0), float(x1), float(y1)


class CourtForeground:
    """Background subtraction restricted to the court, blob extraction and the ground point under a blob."""

    def __init__(self, calibration: CourtCalibration, config: "TrackerConfig") -> None:
        if config.ground_point not in ("foot", "centroid", "auto"):
            raise ValueError(f"ground_point must be 'foot', 'centroid' or 'auto', got {config.ground_point!r}")
        if config.ground_point == "centroid" and not calibration.has_pose:
            raise ValueError("ground_point='centroid' needs a court calibration fitted with camera intrinsics")
        self.calibration = calibration
        self.config = config
        #: The ground-point method in use ("auto" resolved): the parallax-corrected centroid when the pose is known.
        self.ground_point = config.ground_point
        if self.ground_point == "auto":
            self.ground_point = "centroid" if calibration.has_pose else "foot"
        self._mog = cv2.createBackgroundSubtractorMOG2(config.history, config.var_threshold, detectShadows=True)
        self._mog.setNMixtures(config.mixtures)
        width, height = calibration.image_size
        self._roi = np.zeros((height, width), np.uint8)
        outline = calibration.court_to_image(court_outline_m(config.court_margin_m))
        cv2.fillConvexPoly(self._roi, np.round(outline).astype(np.int32), 255)
        self._gain_samples = np.flatnonzero(self._roi.ravel())[::37]  # sparse court pixels for the gain estimate
        self._background: np.ndarray | None = None
        self._background_level = 0.0
        self._open = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
        self._close = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
        self.frames_seen = 0
        self._updates_due = 0

    @property
    def warmed_up(self) -> bool:
        return self.frames_seen >= self.config.warmup_frames

    def _compensate_gain(self, image: np.ndarray) -> np.ndarray:
        """Scale the frame so its court brightness matches the background model's (median ratio over a sparse
        grid of court pixels: the players cover too few of them to move the median). Global lighting changes
        (a cloud, flicker) then never reach the background subtractor."""
        if self._background is None:
            return image
        frame_level = float(np.median(image.reshape(-1, 3)[self._gain_samples].sum(axis=1)))
        ratio = self._background_level / max(frame_level, 1.0)
        return image if abs(ratio - 1.0) < 0.003 else cv2.convertScaleAbs(image, alpha=ratio)

    def _refresh_background(self) -> None:
        self._background = self._mog.getBackgroundImage()
        self._background_level = float(np.median(self._background.reshape(-1, 3)[self._gain_samples].sum(axis=1)))

    def foreground(self, image: np.ndarray) -> np.ndarray:
        """Cleaned foreground mask (uint8 0/255) of one frame; updates the background only during warm-up."""
        if not self.warmed_up:
            raw = self._mog.apply(image, learningRate=-1.0)
        else:
            if self._background is None:
                self._refresh_background()
            raw = self._mog.apply(self._compensate_gain(image), learningRate=0.0)
        self.frames_seen += 1
        mask = np.where(raw == 255, 255, 0).astype(np.uint8) & self._roi
        mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, self._open)
        return cv2.morphologyEx(mask, cv2.MORPH_CLOSE, self._close)

    def blobs(self, mask: np.ndarray) -> list[Blob]:
        """Connected components above ``min_area_px``, largest first."""
        n, labels, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8)
        areas = stats[:, cv2.CC_STAT_AREA]
        order = [i for i in np.argsort(-areas[1:]) + 1 if areas[i] >= self.config.min_area_px]
        out = []
        for i in order:
            x, y, w, h = stats[i, :4]
            ys, xs = np.nonzero(labels[y : y + h, x : x + w] == i)
            pixels = np.column_stack([xs + x, ys + y]).astype(float)
            out.append(Blob(centroids[i].astype(float), float(areas[i]), pixels))
        return out

    def ground_point_m(self, blob: Blob) -> np.ndarray:
        """Court position (2,) m of the player's ground contact under this blob (see the tracker's docstring)."""
        if self.ground_point == "centroid":
            camera = self.calibration.camera_position_m()
            hit = self.calibration.image_to_court(blob.centroid_px[None])[0]
            return camera[:2] + (hit - camera[:2]) * (1.0 - self.config.centroid_height_m / camera[2])
        down = self.calibration.image_down_directions(blob.centroid_px[None])[0]
        along = (blob.pixels_xy - blob.centroid_px) @ down
        foot_px = blob.centroid_px + down * np.percentile(along, self.config.foot_percentile)
        return self.calibration.image_to_court(foot_px[None])[0]

    def learn_around(self, image: np.ndarray, players: Sequence[Blob]) -> None:
        """Background update that cannot learn the players: their (grown) boxes are replaced by the background.
        Called once per frame while at least one player is tracked; learns every ``background_update_every``."""
        cfg = self.config
        self._updates_due += 1
        if not cfg.background_update_every or self._updates_due < cfg.background_update_every:
            return
        self._updates_due = 0
        background = self._background
        if background is None or background.shape != image.shape:
            return
        composite = self._compensate_gain(image).copy()
        h, w = image.shape[:2]
        m = cfg.background_update_margin_px
        for player in players:
            (x0, y0), (x1, y1) = player.pixels_xy.min(axis=0).astype(int), player.pixels_xy.max(axis=0).astype(int)
            x0, y0, x1, y1 = max(x0 - m, 0), max(y0 - m, 0), min(x1 + m + 1, w), min(y1 + m + 1, h)
            composite[y0:y1, x0:x1] = background[y0:y1, x0:x1]
        self._mog.apply(composite, learningRate=cfg.background_learning_rate)
        self._refresh_background()
