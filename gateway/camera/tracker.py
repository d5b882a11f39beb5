"""Single-player tracking on the court: background subtraction -> blob -> ground point -> court metres -> Kalman.

Design choices (why):
- MOG2 background model, learnt during a warm-up on the empty court and then *frozen* for detection
  (``learningRate=0``): a player standing still would otherwise melt into the background. Shadow pixels (MOG2
  label 127) are dropped. Lighting changes must then not turn the whole court into foreground: each frame's
  global gain is first matched to the background's (median over sparse court pixels; clouds, flicker), and the
  model keeps learning *around* the player for slower, local changes: every ``background_update_every`` frames,
  while the player is tracked, it learns a copy of the frame whose player box is filled from the background.
- The foreground is restricted to the court plus a run-off margin, cleaned by opening/closing, and the largest
  blob near the Kalman prediction is the player. The opponent is in view too: ``player_side`` ("near" = y < 0,
  "far" = y > 0) says on which half to *acquire* the instrumented player (at the start, and again after he was
  lost for longer than ``max_coast_s``); once acquired the gate follows him anywhere, across the net at
  changeovers included. Without it the largest blob anywhere is acquired -- the opponent as likely as not.
- Ground point, because the homography is valid for ground pixels only and a 1.8 m body seen obliquely smears
  over metres of ground:
  * ``"foot"``: the blob's extreme along the image direction of "down" at the blob (from the camera pose when
    the court calibration has intrinsics, else image-down), on the blob's axis, 98th percentile for robustness;
  * ``"centroid"``: the blob centroid mapped to the ground, then pulled towards the camera nadir by the factor
    ``1 - h/H`` for a nominal centroid height ``h`` (camera height ``H``) - needs the camera pose. The default
    (``"auto"``) when the pose is known: on the synthetic court its error is ~2.5x smaller than the foot point's,
    whose extreme pixel sits on the toes/heel rather than under the pelvis (see docs/camera-calibration.md).
- Heading follows the seed's rule: direction of motion above 2 m/s, otherwise facing the net, unless an IMU
  heading is supplied (the IMU knows where the trunk faces; the camera does not).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import cv2
import numpy as np

from engine.mocap import seed_heading_rule
from gateway.camera.court import court_outline_m
from gateway.camera.court_calibration import CourtCalibration
from gateway.camera.kalman import ConstantVelocityKalman
from gateway.camera.paths import RUNNING_SPEED_MPS
from gateway.camera.sources import Frame


@dataclass(frozen=True)
class TrackerConfig:
    """Tuning of :class:`PlayerTracker` (defaults suit a 640-1280 px wide view of the whole court)."""

    warmup_frames: int = 25
    history: int = 300
    var_threshold: float = 25.0
    min_area_px: int = 40
    court_margin_m: float = 3.5
    ground_point: str = "auto"          # "foot", "centroid" (needs intrinsics), or "auto" (centroid if possible)
    foot_percentile: float = 98.0
    centroid_height_m: float = 0.9       # best compromise over scripted + CMU clips (bench table 2)
    accel_std_mps2: float = 12.0
    measurement_std_m: float = 0.07
    gate_m: float = 3.0
    max_coast_s: float = 1.0
    background_update_every: int = 5    # frames; 0 = frozen after warm-up
    background_learning_rate: float = 0.02
    background_update_margin_px: int = 12
    running_speed_mps: float = RUNNING_SPEED_MPS
    player_side: str | None = None      # "near" (y < 0) or "far" (y > 0): where to acquire; None = anywhere


@dataclass(frozen=True)
class TrackRecord:
    """One tracker output. ``x_m``/``y_m``/``heading_rad`` are smoothed (court frame, CONTRACTS heading),
    ``confidence`` 0..1 (0 = coasting on prediction only). ``raw_*`` is the unsmoothed ground point of this frame
    (NaN when no blob), ``centroid_px`` and ``blob_area_px`` feed the IMU-camera lag check, ``bbox_px``
    ``(x0, y0, x1, y1)`` is the blob's box (NaN when no blob) for display; ``clutter_px`` counts foreground
    pixels that are not the player (a health metric: it grows when the background model is out of date)."""

    t_host_s: float
    x_m: float
    y_m: float
    heading_rad: float
    confidence: float
    vx_mps: float
    vy_mps: float
    raw_x_m: float
    raw_y_m: float
    centroid_px: tuple[float, float]
    blob_area_px: float
    bbox_px: tuple[float, float, float, float]
    clutter_px: int

    def to_dict(self) -> dict:
        """JSON-ready dict (what the gateway streams on its camera channel)."""
        return asdict(self)


@dataclass(frozen=True)
class Blob:
    centroid_px: np.ndarray
    area_px: float
    pixels_xy: np.ndarray  # (N, 2) x, y


class PlayerTracker:
    """Feed frames in time order with :meth:`update`; returns ``None`` during warm-up and until a player is seen."""

    def __init__(self, calibration: CourtCalibration, config: TrackerConfig = TrackerConfig()) -> None:
        if config.ground_point not in ("foot", "centroid", "auto"):
            raise ValueError(f"ground_point must be 'foot', 'centroid' or 'auto', got {config.ground_point!r}")
        if config.player_side not in (None, "near", "far"):
            raise ValueError(f"player_side must be 'near', 'far' or None, got {config.player_side!r}")
        if config.ground_point == "centroid" and not calibration.has_pose:
            raise ValueError("ground_point='centroid' needs a court calibration fitted with camera intrinsics")
        self.calibration = calibration
        self.config = config
        #: The ground-point method in use ("auto" resolved): the parallax-corrected centroid when the pose is known.
        self.ground_point = config.ground_point
        if self.ground_point == "auto":
            self.ground_point = "centroid" if calibration.has_pose else "foot"
        self._mog = cv2.createBackgroundSubtractorMOG2(config.history, config.var_threshold, detectShadows=True)
        self._kalman = ConstantVelocityKalman(config.accel_std_mps2, config.measurement_std_m)
        width, height = calibration.image_size
        self._roi = np.zeros((height, width), np.uint8)
        outline = calibration.court_to_image(court_outline_m(config.court_margin_m))
        cv2.fillConvexPoly(self._roi, np.round(outline).astype(np.int32), 255)
        self._gain_samples = np.flatnonzero(self._roi.ravel())[::37]  # sparse court pixels for the gain estimate
        self._background: np.ndarray | None = None
        self._background_level = 0.0
        self._open = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
        self._close = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
        self._frames_seen = 0
        self._last_t_s: float | None = None
        self._last_fix_t_s: float | None = None
        self._confidence = 0.0
        self._updates_due = 0

    @property
    def warmed_up(self) -> bool:
        return self._frames_seen >= self.config.warmup_frames

    def _compensate_gain(self, image: np.ndarray) -> np.ndarray:
        """Scale the frame so its court brightness matches the background model's (median ratio over a sparse
        grid of court pixels: the player covers too few of them to move the median). Global lighting changes
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
        """Court position (2,) m of the player's ground contact under this blob (see module docstring)."""
        if self.ground_point == "centroid":
            camera = self.calibration.camera_position_m()
            hit = self.calibration.image_to_court(blob.centroid_px[None])[0]
            return camera[:2] + (hit - camera[:2]) * (1.0 - self.config.centroid_height_m / camera[2])
        down = self.calibration.image_down_directions(blob.centroid_px[None])[0]
        along = (blob.pixels_xy - blob.centroid_px) @ down
        foot_px = blob.centroid_px + down * np.percentile(along, self.config.foot_percentile)
        return self.calibration.image_to_court(foot_px[None])[0]

    def _on_player_side(self, point_m: np.ndarray) -> bool:
        """Can a blob at this court position (m) be acquired as the instrumented player?"""
        side = self.config.player_side
        return side is None or (point_m[1] < 0.0) == (side == "near")

    def _learn_around(self, image: np.ndarray, player: Blob) -> None:
        """Background update that cannot learn the player: his (grown) box is replaced by the background."""
        cfg = self.config
        self._updates_due += 1
        if not cfg.background_update_every or self._updates_due < cfg.background_update_every:
            return
        self._updates_due = 0
        background = self._background
        if background is None or background.shape != image.shape:
            return
        image = self._compensate_gain(image)
        h, w = image.shape[:2]
        m = cfg.background_update_margin_px
        (x0, y0), (x1, y1) = player.pixels_xy.min(axis=0).astype(int), player.pixels_xy.max(axis=0).astype(int)
        x0, y0, x1, y1 = max(x0 - m, 0), max(y0 - m, 0), min(x1 + m + 1, w), min(y1 + m + 1, h)
        composite = image.copy()
        composite[y0:y1, x0:x1] = background[y0:y1, x0:x1]
        self._mog.apply(composite, learningRate=cfg.background_learning_rate)
        self._refresh_background()

    def update(self, frame: Frame, imu_heading_rad: float | None = None) -> TrackRecord | None:
        """Process one frame; ``imu_heading_rad`` (trunk IMU yaw, CONTRACTS convention) overrides the rule."""
        mask = self.foreground(frame.image)
        self._frames_seen += 1
        if not self.warmed_up:
            return None
        cfg = self.config
        dt = 0.0 if self._last_t_s is None else frame.t_host_s - self._last_t_s
        self._last_t_s = frame.t_host_s
        self._kalman.predict(dt)
        chosen: Blob | None = None
        raw = np.full(2, np.nan)
        acquiring = not self._kalman.initialised or (
            self._last_fix_t_s is not None and frame.t_host_s - self._last_fix_t_s > cfg.max_coast_s)
        for blob in self.blobs(mask):
            point = self.ground_point_m(blob)
            if acquiring and self._on_player_side(point) or (
                    not acquiring and self._kalman.innovation_distance_m(point) <= cfg.gate_m):
                chosen, raw = blob, point
                break
        if chosen is not None:
            self._learn_around(frame.image, chosen)
            if acquiring:  # a new track: a stale prediction says nothing about where he is now
                innovation = 0.0
                self._kalman.reset(raw)
            else:
                innovation = self._kalman.innovation_distance_m(raw)
                self._kalman.update(raw)
            self._last_fix_t_s = frame.t_host_s
            self._confidence = float(np.clip(1.0 - innovation / cfg.gate_m, 0.1, 1.0))
        elif self._last_fix_t_s is None or frame.t_host_s - self._last_fix_t_s > cfg.max_coast_s:
            return None  # never seen, or lost for too long: report nothing rather than a guess
        else:
            self._confidence = 0.0
        x, y, vx, vy = self._kalman.state
        if imu_heading_rad is not None:
            heading = float(imu_heading_rad)
        else:
            heading = float(seed_heading_rule((x, y), (vx, vy), cfg.running_speed_mps))
        nan = float("nan")
        if chosen is not None:
            centroid = (float(chosen.centroid_px[0]), float(chosen.centroid_px[1]))
            (x0, y0), (x1, y1) = chosen.pixels_xy.min(axis=0), chosen.pixels_xy.max(axis=0) + 1
            bbox = (float(x0), float(y0), float(x1), float(y1))
        else:
            centroid, bbox = (nan, nan), (nan, nan, nan, nan)
        return TrackRecord(
            frame.t_host_s, float(x), float(y), heading, self._confidence, float(vx), float(vy),
            float(raw[0]), float(raw[1]), centroid, chosen.area_px if chosen else nan, bbox,
            int(cv2.countNonZero(mask)) - int(chosen.area_px if chosen else 0),
        )
