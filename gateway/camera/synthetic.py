"""Synthetic overhead court camera: renders a tennis court and a 3-D player with exact ground truth.

Why: there is no camera in CI. The renderer uses a known :class:`PinholeCamera`, so the court homography, the
player's court position and heading, and each frame's true exposure time are known exactly; the tracker is scored
against them. Realism that matters to the tracker is modelled: oblique view (parallax), a cast shadow
(background subtraction must drop it), slow lighting drift and flicker, sensor noise, dropped frames and host
timestamp jitter/latency.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from collections.abc import Callable, Sequence

from gateway.camera.body import Capsules, body_capsules, capsule_surface_points, STRIDE_M
from gateway.camera.court import COURT_LINES_M, HALF_DOUBLES_M, HALF_LENGTH_M, LINE_WIDTH_M
from gateway.camera.paths import PlayerPath, PlayerState
from gateway.camera.pinhole import PinholeCamera
from gateway.camera.sources import Frame, _IterableSource

COURT_BGR = (150, 100, 45)        # blue hard court inside the lines
SURROUND_BGR = (80, 120, 70)      # green run-off
LINE_BGR = (235, 235, 235)
NET_BGR = (30, 30, 30)
_SUBPIXEL_BITS = 4                # cv2 fill with 1/16 px vertex precision


def default_court_camera(image_size: tuple[int, int] = (800, 450)) -> PinholeCamera:
    """A camera 18 m up, 1.5 m outside the left doubles sideline, aimed at the court centre: slightly oblique, the
    whole court and run-off in view, court length across the image."""
    width, _ = image_size
    return PinholeCamera.look_at((-7.0, 0.0, 18.0), (0.0, 0.0, 0.0), focal_px=0.6 * width,
                                 image_size=image_size, image_up_hint=(1.0, 0.0, 0.0))


@dataclass(frozen=True)
class GroundTruth:
    """What really happened in a synthetic frame: true exposure time (s), player ground position (m), heading
    (rad), lift (m), and whether the player was on court (false during the empty-court warm-up)."""

    t_true_s: float
    x_m: float
    y_m: float
    heading_rad: float
    lift_m: float
    visible: bool


@dataclass(frozen=True)
class CameraImperfections:
    """Noise model. ``latency_s`` is added to every timestamp (the IMU-camera lag the lag check must find)."""

    sensor_noise_dn: float = 2.5
    flicker: float = 0.01           # per-frame relative gain std
    drift: float = 0.03             # slow relative gain amplitude (clouds)
    drift_period_s: float = 9.0
    drift_tilt: float = 0.0         # amplitude of a left-right gain gradient (sun moving): a local change
    drop_probability: float = 0.0
    jitter_s: float = 0.0           # host timestamp std
    latency_s: float = 0.0
    shadow_gain: float = 0.6        # brightness of shadowed court
    sun_direction: tuple[float, float, float] = (0.35, -0.25, -1.0)


def render_court_background(camera: PinholeCamera, metres_per_px: float = 0.02) -> np.ndarray:
    """The empty court (BGR) as this camera sees it: a top-down court texture warped by the ground homography,
    plus the net (a vertical band drawn in 3-D)."""
    margin_x, margin_y = 8.0, 8.0
    x0, y0 = -HALF_DOUBLES_M - margin_x, -HALF_LENGTH_M - margin_y
    tex_w = int(round(2 * (HALF_DOUBLES_M + margin_x) / metres_per_px))
    tex_h = int(round(2 * (HALF_LENGTH_M + margin_y) / metres_per_px))
    texture = np.empty((tex_h, tex_w, 3), np.uint8)
    texture[:] = SURROUND_BGR

    def tex_px(points_m: np.ndarray) -> np.ndarray:
        return np.round(((np.asarray(points_m) - [x0, y0]) / metres_per_px) * (1 << _SUBPIXEL_BITS)).astype(np.int32)

    inner = np.array([[-HALF_DOUBLES_M, -HALF_LENGTH_M], [HALF_DOUBLES_M, -HALF_LENGTH_M],
                      [HALF_DOUBLES_M, HALF_LENGTH_M], [-HALF_DOUBLES_M, HALF_LENGTH_M]])
    grow = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * 1.5
    cv2.fillConvexPoly(texture, tex_px(inner + grow), COURT_BGR, cv2.LINE_AA, _SUBPIXEL_BITS)
    thickness = max(1, int(round(LINE_WIDTH_M / metres_per_px)))
    for line in COURT_LINES_M.values():
        a, b = tex_px(line)
        cv2.line(texture, tuple(map(int, a)), tuple(map(int, b)), LINE_BGR, thickness, cv2.LINE_AA, _SUBPIXEL_BITS)
    # texture pixel -> court metres -> image
    half = metres_per_px / 2
    tex_to_court = np.array([[metres_per_px, 0, x0 + half], [0, metres_per_px, y0 + half], [0, 0, 1]])
    warp = camera.ground_homography() @ tex_to_court
    image = cv2.warpPerspective(texture, warp, camera.image_size, flags=cv2.INTER_AREA, borderValue=SURROUND_BGR)
    net_x = HALF_DOUBLES_M + 0.914
    net = np.array([[-net_x, 0, 0], [net_x, 0, 0], [net_x, 0, 1.07], [-net_x, 0, 1.07]])
    overlay = image.copy()
    cv2.fillConvexPoly(overlay, _subpx(camera.project(net)), NET_BGR, cv2.LINE_AA, _SUBPIXEL_BITS)
    return cv2.addWeighted(overlay, 0.45, image, 0.55, 0.0)


def _subpx(points_px: np.ndarray) -> np.ndarray:
    return np.round(points_px * (1 << _SUBPIXEL_BITS)).astype(np.int32)


class SyntheticCourtCamera(_IterableSource):
    """Frames of a player following ``path`` on a rendered court, with :class:`GroundTruth` in ``frame.truth``.

    Frames are produced at ``fps`` for the path's duration; the first ``empty_s`` seconds show an empty court
    (the operator starts the camera before the player walks on, which is when the tracker learns the background).
    Frame ``k`` is exposed at ``t0_s + k / fps`` (true time); its ``t_host_s`` adds latency and jitter.
    ``body(t_s, state, gait_phase_rad) -> Capsules`` draws the player: the parametric runner by default, or a
    :class:`gateway.camera.mocap_body.MocapBody` (whose ``.path`` is then the matching ``path``).
    ``opponents``: more players (parametric runners) drawn on the same court -- distractors the tracker must not
    follow; the ground truth stays the player's.
    """

    def __init__(
        self, path: PlayerPath, *, camera: PinholeCamera | None = None, fps: float = 30.0, empty_s: float = 1.0,
        imperfections: CameraImperfections = CameraImperfections(), seed: int = 0,
        body: Callable[[float, PlayerState, float], Capsules] | None = None, opponents: Sequence[PlayerPath] = (),
    ) -> None:
        self.camera = camera or default_court_camera()
        self.path = path
        self.nominal_fps = fps
        self.image_size = self.camera.image_size
        self.empty_s = empty_s
        self.imperfections = imperfections
        self._body = body or (lambda t_s, state, phase: body_capsules(state, phase))
        self._rng = np.random.default_rng(seed)
        self._background = render_court_background(self.camera).astype(np.float32)
        self._homography = self.camera.ground_homography()
        # Sensor noise: one of 8 pre-drawn independent fields per frame, at random. Per-pixel statistics are those
        # of fresh noise (what background subtraction sees) at a fraction of the cost of drawing 1M normals a frame.
        shape = self._background.shape
        self._noise_bank = [self._rng.standard_normal(shape, dtype=np.float32) * imperfections.sensor_noise_dn
                            for _ in range(8)] if imperfections.sensor_noise_dn else []
        self._t0_s = float(path.t_s[0]) - empty_s
        self._n_frames = int(np.floor((path.duration_s + empty_s) * fps)) + 1
        self._k = 0
        self.opponents = list(opponents)
        self._gait_phase = np.zeros(1 + len(self.opponents))  # the player's, then each opponent's
        self._last_t_s = self._t0_s
        self.dropped = 0

    @property
    def next_t_true_s(self) -> float | None:
        """True time of the frame `read` renders next (None after the last one)."""
        return self._t0_s + self._k / self.nominal_fps if self._k < self._n_frames else None

    def skip_to(self, t_true_s: float) -> int:
        """Jump ahead without rendering: the next frame is the first at or after ``t_true_s``; returns how many
        frames were skipped (counted as dropped). Why: a real camera whose consumer falls behind never delivers the
        frames in between, so a renderer paced to the wall clock that cannot keep up must not fall seconds behind
        it either. The gait phases integrate over the jump, so the bodies stay continuous in time."""
        k = min(max(self._k, int(np.ceil((t_true_s - self._t0_s) * self.nominal_fps - 1e-9))), self._n_frames)
        skipped, self._k = k - self._k, k
        self.dropped += skipped
        return skipped

    def read(self) -> Frame | None:
        imp = self.imperfections
        while self._k < self._n_frames:
            k = self._k
            self._k += 1
            t_true = self._t0_s + k / self.nominal_fps
            state = self.path.state(t_true)
            others = [p.state(t_true) for p in self.opponents]
            speeds = np.array([st.speed_mps for st in [state, *others]])
            self._gait_phase += 2 * np.pi * speeds * (t_true - self._last_t_s) / STRIDE_M
            self._last_t_s = t_true
            if self._rng.random() < imp.drop_probability:
                self.dropped += 1
                continue
            visible = t_true >= self.path.t_s[0]
            bodies = [self._body(t_true, state, self._gait_phase[0])] if visible else []
            bodies += [body_capsules(st, phase) for st, phase, p in zip(others, self._gait_phase[1:], self.opponents)
                       if t_true >= p.t_s[0]]
            image = self._render(bodies, t_true)
            t_host = t_true + imp.latency_s + (self._rng.normal(0.0, imp.jitter_s) if imp.jitter_s else 0.0)
            truth = GroundTruth(t_true, state.x_m, state.y_m, state.heading_rad, state.lift_m, visible)
            return Frame(k, t_host, image, truth)
        return None

    def _render(self, bodies: list[Capsules], t_true_s: float) -> np.ndarray:
        imp = self.imperfections
        img = self._background.copy()
        if bodies:
            pts = np.concatenate([capsule_surface_points(caps) for caps in bodies])  # (C, P, 3), every body
            start = np.concatenate([caps.start_m for caps in bodies])
            end = np.concatenate([caps.end_m for caps in bodies])
            colour = [c for caps in bodies for c in caps.colour]
            sun = np.asarray(imp.sun_direction, float)
            ground = pts - (pts[..., 2:3] / sun[2]) * sun  # along the sun ray onto z = 0
            shadow = np.zeros(img.shape[:2], np.uint8)
            for poly in ground:
                hull = cv2.convexHull(_subpx(self._project_ground(poly[:, :2])))
                cv2.fillConvexPoly(shadow, hull, 255, cv2.LINE_AA, _SUBPIXEL_BITS)
            x, y, w, h = cv2.boundingRect(shadow)  # darken only where the shadow is (speed)
            if w and h:
                darkness = (1.0 - imp.shadow_gain) * (shadow[y : y + h, x : x + w].astype(np.float32) / 255.0)
                img[y : y + h, x : x + w] *= (1.0 - darkness)[..., None]
            canvas = img.astype(np.uint8)
            depth = np.linalg.norm(start + end - 2 * self.camera.position_m, axis=1)
            flat = self.camera.project(pts.reshape(-1, 3)).reshape(pts.shape[0], pts.shape[1], 2)
            for i in np.argsort(-depth):  # far capsules first
                hull = cv2.convexHull(_subpx(flat[i]))
                cv2.fillConvexPoly(canvas, hull, colour[i], cv2.LINE_AA, _SUBPIXEL_BITS)
            img = canvas.astype(np.float32)
        slow = np.sin(2 * np.pi * t_true_s / imp.drift_period_s)
        gain = 1.0 + imp.drift * slow + self._rng.normal(0.0, imp.flicker)
        if imp.drift_tilt:
            ramp = np.linspace(-1.0, 1.0, img.shape[1], dtype=np.float32)
            img *= (gain + imp.drift_tilt * slow * ramp)[None, :, None]
        else:
            img *= gain
        if imp.sensor_noise_dn:
            img += self._noise_bank[self._rng.integers(len(self._noise_bank))]
        return np.clip(img, 0, 255).astype(np.uint8)

    def _project_ground(self, points_m: np.ndarray) -> np.ndarray:
        homog = np.column_stack([points_m, np.ones(len(points_m))]) @ self._homography.T
        return homog[:, :2] / homog[:, 2:3]
