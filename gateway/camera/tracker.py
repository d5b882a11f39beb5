"""Player tracking on the court: background subtraction -> blobs -> ground points -> tracks (one per athlete).

Design choices (why):
- MOG2 background model, learnt during a warm-up on the empty court and then *frozen* for detection
  (``learningRate=0``): a player standing still would otherwise melt into the background. Shadow pixels (MOG2
  label 127) are dropped. Lighting changes must then not turn the whole court into foreground: each frame's
  global gain is first matched to the background's (median over sparse court pixels; clouds, flicker), and the
  model keeps learning *around* the player for slower, local changes: every ``background_update_every`` frames,
  while the player is tracked, it learns a copy of the frame whose player box is filled from the background.
- Detection (background model, morphology, blobs) runs at ``1 / detect_downscale`` resolution, half by default:
  a quarter of the CPU, and blobs are reported in full-resolution pixels (:mod:`gateway.camera.foreground`).
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
- Several athletes (:class:`MultiPlayerTracker`, one track each, e.g. singles tennis): one detector
  (:class:`gateway.camera.foreground.CourtForeground`) per frame, blobs assigned to the tracks' Kalman predictions
  by a minimum-total-distance assignment inside the gate (never two tracks on one blob). When two players merge
  into one blob (crossing at the net, one occluding the other) the blob lies within ``merge_radius_m`` of both
  predictions: *both* tracks then coast on their constant-velocity prediction instead of one of them taking the
  merged blob's midpoint, and the assignment sorts them out when the blobs separate - identity follows motion
  continuity, not blob size. A track without a fix for ``max_coast_s`` is *lost* (reported as such, no position)
  and re-acquired from blobs that no live track can claim, on the side of the court where it was last seen (its
  configured side before its first fix).
- Heading follows the seed's rule: direction of motion above 2 m/s, otherwise facing the net, unless an IMU
  heading is supplied (the IMU knows where the trunk faces; the camera does not).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from itertools import product

import numpy as np

from engine.heading import seed_heading_rule
from gateway.athletes import DEFAULT_ATHLETE
from gateway.camera.court_calibration import CourtCalibration
from gateway.camera.foreground import Blob, CourtForeground
from gateway.camera.kalman import ConstantVelocityKalman
from gateway.camera.paths import RUNNING_SPEED_MPS
from gateway.camera.sources import Frame

SIDES = ("near", "far")


@dataclass(frozen=True)
class TrackerConfig:
    """Tuning of the trackers (defaults suit a 640-1280 px wide view of the whole court)."""

    warmup_frames: int = 25
    history: int = 300
    var_threshold: float = 25.0
    mixtures: int = 3                   # MOG2 Gaussians per pixel (OpenCV's default 5): the model is frozen after
                                        # warm-up, so 3 track identically here and save 40 % of its memory (board)
    min_area_px: int = 40               # full-resolution pixels, as every *_px below
    detect_downscale: int = 2           # background subtraction, morphology and blobs at 1/n resolution (1 = full):
                                        # a quarter of the pixels, a quarter of the CPU (the board's budget)
    court_margin_m: float = 3.5
    ground_point: str = "auto"          # "foot", "centroid" (needs intrinsics), or "auto" (centroid if possible)
    foot_percentile: float = 98.0
    centroid_height_m: float = 0.9       # best compromise over scripted + CMU clips (bench table 2)
    accel_std_mps2: float = 12.0
    measurement_std_m: float = 0.07
    gate_m: float = 3.0
    merge_radius_m: float = 1.2         # a blob this close to two predictions may hold both players: coast both
    max_coast_s: float = 1.0
    background_update_every: int = 10   # frames; 0 = frozen after warm-up. Every 10 at 0.04 adapts as fast as
    background_learning_rate: float = 0.04  # every 5 at 0.02 (0.12 per second at 30 fps) at half the CPU
    background_update_margin_px: int = 12
    running_speed_mps: float = RUNNING_SPEED_MPS
    player_side: str | None = None      # "near" (y < 0) or "far" (y > 0): where to acquire; None = anywhere


@dataclass(frozen=True)
class TrackRecord:
    """One tracker output. ``x_m``/``y_m``/``heading_rad`` are smoothed (court frame, CONTRACTS heading),
    ``confidence`` 0..1 (0 = coasting on prediction only). ``raw_*`` is the unsmoothed ground point of this frame
    (NaN when no blob), ``centroid_px`` and ``blob_area_px`` feed the IMU-camera lag check, ``bbox_px``
    ``(x0, y0, x1, y1)`` is the blob's box (NaN when no blob) for display; ``clutter_px`` counts foreground
    pixels that are not a tracked player (a health metric: it grows when the background model is out of date).
    ``athlete`` names whose track this is."""

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
    athlete: str = DEFAULT_ATHLETE

    def to_dict(self) -> dict:
        """JSON-ready dict (what the gateway streams on its camera channel)."""
        return asdict(self)


class _Track:
    """One athlete's Kalman track and its life cycle: searching -> tracking <-> coasting -> lost -> tracking."""

    def __init__(self, name: str, side: str | None, config: TrackerConfig) -> None:
        if side not in (None, *SIDES):
            raise ValueError(f"player_side must be 'near', 'far' or None, got {side!r}")
        self.name = name
        self.side = side  # where to (re-)acquire: the configured side, then the side of the last fix
        self.kalman = ConstantVelocityKalman(config.accel_std_mps2, config.measurement_std_m)
        self.max_coast_s = config.max_coast_s
        self.last_fix_t_s: float | None = None
        self.confidence = 0.0
        self.losses = 0

    def status(self, t_s: float) -> str:
        """"searching" (never seen), "tracking" (fixed now), "coasting" (on prediction) or "lost"."""
        if self.last_fix_t_s is None:
            return "searching"
        if t_s - self.last_fix_t_s > self.max_coast_s:
            return "lost"
        return "tracking" if self.last_fix_t_s == t_s else "coasting"

    def live(self, t_s: float) -> bool:
        """Has a position worth gating against (fixed within ``max_coast_s``)?"""
        return self.last_fix_t_s is not None and t_s - self.last_fix_t_s <= self.max_coast_s

    def may_acquire(self, point_m: np.ndarray) -> bool:
        return self.side is None or (point_m[1] < 0.0) == (self.side == "near")

    def fix(self, point_m: np.ndarray, t_s: float, gate_m: float) -> None:
        """Fuse a measurement; a lost or new track restarts there (a stale prediction says nothing)."""
        if not self.live(t_s):
            if self.last_fix_t_s is not None:
                self.losses += 1
            innovation = 0.0
            self.kalman.reset(point_m)
        else:
            innovation = self.kalman.innovation_distance_m(point_m)
            self.kalman.update(point_m)
        if self.side is not None:
            self.side = "near" if point_m[1] < 0.0 else "far"
        self.last_fix_t_s = t_s
        self.confidence = float(np.clip(1.0 - innovation / gate_m, 0.1, 1.0))


def _min_distance_assignment(dist_m: np.ndarray, gate_m: float) -> dict[int, int]:
    """Row -> column of the assignment with the most pairs inside the gate, then the least total distance.

    Exhaustive over the blobs inside each track's gate: a court has a handful of athletes and each gate holds
    one or two blobs, so this is a few dozen candidates (and spares the board scipy.optimize's ~30 MB)."""
    candidates = [[int(b) for b in np.flatnonzero(row <= gate_m)] + [-1] for row in dist_m]
    best: tuple[int, float, tuple[int, ...]] = (0, 0.0, tuple(-1 for _ in candidates))
    for combo in product(*candidates):
        taken = [b for b in combo if b >= 0]
        if len(set(taken)) != len(taken):
            continue
        score = (len(taken), -sum(dist_m[r, b] for r, b in enumerate(combo) if b >= 0))
        if score > best[:2]:
            best = (*score, combo)
    return {r: b for r, b in enumerate(best[2]) if b >= 0}


class MultiPlayerTracker:
    """Tracks several athletes with one detector: ``athletes`` maps each name to the side ("near"/"far", or None
    for anywhere) where it is first acquired. Feed frames in time order with :meth:`update`."""

    def __init__(self, calibration: CourtCalibration, athletes: Mapping[str, str | None],
                 config: TrackerConfig = TrackerConfig()) -> None:
        if not athletes:
            raise ValueError("at least one athlete to track")
        self.detector = CourtForeground(calibration, config)
        self.calibration = calibration
        self.config = config
        self.tracks = [_Track(name, side, config) for name, side in athletes.items()]
        self._last_t_s: float | None = None

    @property
    def ground_point(self) -> str:
        return self.detector.ground_point

    @property
    def names(self) -> list[str]:
        return [tr.name for tr in self.tracks]

    def status(self) -> dict[str, str]:
        """Each athlete's track state at the last frame (see :meth:`_Track.status`)."""
        t = self._last_t_s if self._last_t_s is not None else 0.0
        return {tr.name: tr.status(t) for tr in self.tracks}

    def _assign(self, t_s: float, points: list[np.ndarray]) -> tuple[dict[int, int], set[int]]:
        """Blob index per live track (gated minimum-distance assignment) and the blobs held back as merged."""
        cfg = self.config
        live = [i for i, tr in enumerate(self.tracks) if tr.live(t_s)]
        if not live or not points:
            return {}, set()
        dist = np.array([[self.tracks[i].kalman.innovation_distance_m(p) for p in points] for i in live])
        chosen = {live[r]: b for r, b in _min_distance_assignment(dist, cfg.gate_m).items()}
        merged = set()
        for r, i in enumerate(live):
            if i in chosen:
                continue
            for j, b in list(chosen.items()):  # an unmatched live track right at a matched blob: both inside it
                if dist[r, b] <= cfg.merge_radius_m:
                    merged.add(chosen.pop(j))
        return chosen, merged

    def _acquire(self, t_s: float, points: list[np.ndarray], taken: set[int]) -> dict[int, int]:
        """Blobs (largest first) for tracks that are not live: on their side, and not claimable by a live track."""
        cfg = self.config
        live = [tr for tr in self.tracks if tr.live(t_s)]
        out: dict[int, int] = {}
        for i, tr in enumerate(self.tracks):
            if tr.live(t_s):
                continue
            for b, p in enumerate(points):
                if b in taken or not tr.may_acquire(p):
                    continue
                if any(other.kalman.innovation_distance_m(p) <= cfg.gate_m for other in live):
                    continue
                out[i] = b
                taken.add(b)
                break
        return out

    def update_all(self, frame: Frame, imu_headings_rad: Mapping[str, float] | None = None
                   ) -> dict[str, TrackRecord | None]:
        """Process one frame. Returns each athlete's record (None during warm-up, while searching and when lost).
        ``imu_headings_rad``: trunk IMU yaw per athlete (CONTRACTS convention), overriding the heading rule."""
        mask = self.detector.foreground(frame.image)
        if not self.detector.warmed_up:
            return {tr.name: None for tr in self.tracks}
        cfg = self.config
        t = frame.t_host_s
        dt = 0.0 if self._last_t_s is None else t - self._last_t_s
        self._last_t_s = t
        for tr in self.tracks:
            tr.kalman.predict(dt)
        blobs = self.detector.blobs(mask)
        points = [self.detector.ground_point_m(b) for b in blobs]
        chosen, merged = self._assign(t, points)
        chosen.update(self._acquire(t, points, set(chosen.values()) | merged))
        for i, b in chosen.items():
            self.tracks[i].fix(points[b], t, cfg.gate_m)
        in_use = [blobs[b] for b in set(chosen.values()) | merged]
        if in_use and all(tr.live(t) for tr in self.tracks):  # never learn a player who is out of track
            self.detector.learn_around(in_use)
        clutter = self.detector.mask_area_px(mask) - int(sum(b.area_px for b in in_use))
        headings = imu_headings_rad or {}
        out: dict[str, TrackRecord | None] = {}
        for i, tr in enumerate(self.tracks):
            blob = blobs[chosen[i]] if i in chosen else None
            if blob is None and tr.live(t):
                tr.confidence = 0.0
            out[tr.name] = self._record(tr, t, blob, points[chosen[i]] if blob else None, clutter,
                                        headings.get(tr.name)) if tr.live(t) else None
        return out

    update = update_all  # several athletes: a dict per frame (PlayerTracker's update returns the one record)

    def _record(self, tr: _Track, t_s: float, blob: Blob | None, raw_m: np.ndarray | None, clutter_px: int,
                imu_heading_rad: float | None) -> TrackRecord:
        x, y, vx, vy = tr.kalman.state
        if imu_heading_rad is not None:
            heading = float(imu_heading_rad)
        else:
            heading = float(seed_heading_rule((x, y), (vx, vy), self.config.running_speed_mps))
        nan = float("nan")
        if blob is not None:
            centroid = (float(blob.centroid_px[0]), float(blob.centroid_px[1]))
            bbox, area, raw = blob.bbox_px(), blob.area_px, (float(raw_m[0]), float(raw_m[1]))
        else:
            centroid, bbox, area, raw = (nan, nan), (nan, nan, nan, nan), nan, (nan, nan)
        return TrackRecord(t_s, float(x), float(y), heading, tr.confidence, float(vx), float(vy), raw[0], raw[1],
                           centroid, area, bbox, clutter_px, tr.name)


class PlayerTracker(MultiPlayerTracker):
    """One athlete: feed frames in time order with :meth:`update`; returns ``None`` during warm-up and until a
    player is seen. ``config.player_side`` says where to acquire him when an opponent is in view too."""

    def __init__(self, calibration: CourtCalibration, config: TrackerConfig = TrackerConfig(),
                 athlete: str = DEFAULT_ATHLETE) -> None:
        super().__init__(calibration, {athlete: config.player_side}, config)

    def update(self, frame: Frame, imu_heading_rad: float | None = None) -> TrackRecord | None:  # type: ignore[override]
        """Process one frame; ``imu_heading_rad`` (trunk IMU yaw, CONTRACTS convention) overrides the rule."""
        name = self.tracks[0].name
        return self.update_all(frame, None if imu_heading_rad is None else {name: imu_heading_rad})[name]
