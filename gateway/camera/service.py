"""Camera hook for the gateway daemon: a thread that reads frames, tracks the player and calls the sink.

Contract (docs/gateway.md "Hooks"): ``start(sink)`` / ``stop()``; ``sink(observation: dict, jpeg: bytes | None)``
with at least ``t_host_s``, ``position_m`` ``[x, y]`` (court frame) and ``heading_rad``. We add ``confidence``,
``velocity_mps``, ``raw_position_m``, ``frame_index`` and ``tracking`` (False while warming up / lost; no
position then), and for the console's overlay ``court_to_image`` (3x3, court metres -> *thumbnail* pixels) and
``bbox_px`` ``[x0, y0, x1, y1]`` (thumbnail pixels) of the player's blob.

Several athletes (a :class:`MultiPlayerTracker`): one observation per athlete per frame, each with ``athlete``
(its name) and ``status`` (``searching`` / ``tracking`` / ``coasting`` / ``lost``: a lost track is reported as
such, without a position, until it is re-acquired); the thumbnail rides on the first athlete's observation.

Why a thumbnail only every few frames: the console shows the camera picture for orientation; positions are the
data. JPEG encoding every frame would cost more CPU than tracking on a small board.
"""
from __future__ import annotations

import collections
import logging
import threading
import time
from dataclasses import replace
from collections.abc import Mapping
from typing import Any, Callable

import cv2
import numpy as np

from gateway.athletes import DEFAULT_ATHLETE
from gateway.camera.sources import Frame, FrameSource
from gateway.camera.tracker import MultiPlayerTracker, TrackRecord

log = logging.getLogger(__name__)
Sink = Callable[[dict[str, Any], "bytes | None"], None]


def observation(frame: Frame, record: TrackRecord | None, court_to_image: np.ndarray, scale: float,
                athlete: str = DEFAULT_ATHLETE, status: str | None = None) -> dict[str, Any]:
    """The dict sent to the gateway for one athlete in one frame; ``scale`` maps frame pixels to thumbnail pixels."""
    out: dict[str, Any] = {"t_host_s": frame.t_host_s, "frame_index": frame.index, "tracking": record is not None,
                           "court_to_image": court_to_image.tolist(), "athlete": athlete}
    if status is not None:
        out["status"] = status
    if record is None:
        return out
    out.update({
        "t_host_s": record.t_host_s, "position_m": [record.x_m, record.y_m], "heading_rad": record.heading_rad,
        "confidence": record.confidence, "velocity_mps": [record.vx_mps, record.vy_mps],
        "raw_position_m": [record.raw_x_m, record.raw_y_m],
    })
    if np.isfinite(record.bbox_px[0]):
        out["bbox_px"] = [v * scale for v in record.bbox_px]
    return out


class CameraService:
    """Runs ``source`` through ``tracker`` on a thread.

    ``realtime=True`` is for recorded or synthetic sources: frame times are shifted onto ``time.monotonic()``
    at start and the thread waits until each frame is due, so the gateway sees a live-like stream. Live cameras
    (``OpenCVCamera``) already carry monotonic times and pace themselves.
    """

    def __init__(self, source: FrameSource, tracker: MultiPlayerTracker, *, realtime: bool = False,
                 thumbnail_every: int = 10, thumbnail_width_px: int = 320, jpeg_quality: int = 70,
                 loop: bool = False, label: str = "") -> None:
        self.source = source
        self.loop = loop
        self.label = label or type(source).__name__
        self.tracker = tracker
        self.realtime = realtime
        self.thumbnail_every = thumbnail_every
        self.thumbnail_width_px = thumbnail_width_px
        self.jpeg_quality = jpeg_quality
        width = tracker.calibration.image_size[0]
        self._scale = thumbnail_width_px / width
        self._court_to_image = np.diag([self._scale, self._scale, 1.0]) @ tracker.calibration.homography
        self.frames = 0
        self.tracked = 0
        self.dropped = 0  # frames the source skipped (gaps in Frame.index)
        self.loops = 0
        self.state = "starting"  # -> running -> ended (end of a file) / failed (error) / stopped
        self.error: str | None = None
        self._last_index: int | None = None
        self._last_confidence: float | None = None
        self._last_status: dict[str, str] = {}
        self._recent_s: collections.deque[float] = collections.deque(maxlen=256)  # arrival times (monotonic)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @classmethod
    def synthetic(cls, seconds: float = 600.0, *, seed: int = 0, clip: str | None = None,
                  thumbnail_every: int = 10, athletes: Mapping[str, str | None] | None = None) -> "CameraService":
        """A paced synthetic court camera (scripted rally, or a shipped CMU ``clip``) with its exact calibration:
        the camera of ``courtside gateway --emulate`` and the demo. ``athletes`` ``{name: side}`` with two
        entries: the near one follows the rally (or clip), the far one a scripted rally of his own on the far
        half, and one track is kept per athlete; default: one athlete, "player", acquired anywhere."""
        from gateway.camera.court import COURT_KEYPOINTS_M, keypoints_array
        from gateway.camera.court_calibration import CourtCalibration
        from gateway.camera.paths import scripted_rally_path
        from gateway.camera.synthetic import SyntheticCourtCamera, default_court_camera

        camera = default_court_camera()
        names = list(COURT_KEYPOINTS_M)
        clicks = camera.project(np.column_stack([keypoints_array(names), np.zeros(len(names))]))
        calibration = CourtCalibration.fit(clicks, names=names, image_size=camera.image_size,
                                           camera_matrix=camera.camera_matrix)
        body = None
        if clip is not None:
            from engine.mocap import load_clip, sample_clips
            from gateway.camera.mocap_body import MocapBody

            body = MocapBody(load_clip(sample_clips()[clip], fps=30.0))
            path = body.path
        else:
            path = scripted_rally_path(seconds, seed=seed)
        athletes = dict(athletes or {DEFAULT_ATHLETE: None})
        opponents = [scripted_rally_path(path.duration_s, seed=seed + 1, side="far", start_s=float(path.t_s[0]))
                     ] if len(athletes) > 1 else []
        source = SyntheticCourtCamera(path, camera=camera, body=body, seed=seed, opponents=opponents)
        return cls(source, MultiPlayerTracker(calibration, athletes), realtime=True, thumbnail_every=thumbnail_every)

    def start(self, sink: Sink) -> None:
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, args=(sink,), name="camera", daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 5.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
        self.source.close()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def health(self, window_s: float = 2.0) -> dict[str, Any]:
        """What the gateway's status reports about the camera: state, measured fps over the last ``window_s``,
        frames, dropped frames, frames with a track, and the newest track confidence (None while not tracking);
        ``athletes``: each athlete's track status (searching / tracking / coasting / lost)."""
        now = time.monotonic()
        recent = [t for t in list(self._recent_s) if now - t <= window_s]
        fps = (len(recent) - 1) / (recent[-1] - recent[0]) if len(recent) > 2 and recent[-1] > recent[0] else 0.0
        return {"source": self.label, "state": self.state, "fps": round(fps, 2),
                "nominal_fps": float(self.source.nominal_fps), "frames": self.frames, "dropped": self.dropped,
                "tracked": self.tracked, "tracking": self._last_confidence is not None,
                "confidence": self._last_confidence, "loops": self.loops, "error": self.error,
                "athletes": dict(self._last_status)}

    def _count(self, frame: Frame, records: dict[str, TrackRecord | None]) -> None:
        if self._last_index is not None and frame.index > self._last_index + 1:
            self.dropped += frame.index - self._last_index - 1
        self._last_index = frame.index
        self.frames += 1
        live = [r for r in records.values() if r is not None]
        self.tracked += bool(live)
        self._last_confidence = min(float(r.confidence) for r in live) if live else None
        status = self.tracker.status()
        for name, now in status.items():
            if now == "lost" and self._last_status.get(name) != "lost":
                log.warning("camera %s: lost %s (no blob for %.1f s); re-acquiring on the %s side", self.label,
                            name, self.tracker.config.max_coast_s, next(t.side for t in self.tracker.tracks
                                                                        if t.name == name) or "either")
        self._last_status = status
        self._recent_s.append(time.monotonic())

    def _thumbnail(self, frame: Frame) -> bytes | None:
        if not self.thumbnail_every or frame.index % self.thumbnail_every:
            return None
        h, w = frame.image.shape[:2]
        small = cv2.resize(frame.image, (self.thumbnail_width_px, max(1, round(h * self.thumbnail_width_px / w))),
                           interpolation=cv2.INTER_AREA)
        ok, data = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        return data.tobytes() if ok else None

    def _next_frame(self) -> Frame | None:
        frame = self.source.read()
        rewind = getattr(self.source, "rewind", None)
        if frame is None and self.loop and rewind is not None and self.frames:
            rewind()  # a looping demo court: play the file again
            self.loops += 1
            self._last_index = None
            frame = self.source.read()
        return frame

    def _run(self, sink: Sink) -> None:
        offset_s: float | None = None
        last_t_s = -np.inf
        try:
            self.state = "running"
            while not self._stop.is_set():
                frame = self._next_frame()
                if frame is None:
                    self.state = "ended"
                    log.warning("camera %s: end of stream after %d frames", self.label, self.frames)
                    break
                if self.realtime:
                    if offset_s is None or frame.t_host_s + offset_s <= last_t_s:  # start, or a loop restarted
                        offset_s = time.monotonic() - frame.t_host_s
                    frame = replace(frame, t_host_s=frame.t_host_s + offset_s)
                    if self._stop.wait(max(0.0, frame.t_host_s - time.monotonic())):
                        break
                last_t_s = frame.t_host_s
                records = self.tracker.update_all(frame)
                self._count(frame, records)
                jpeg = self._thumbnail(frame)
                for name, record in records.items():
                    sink(observation(frame, record, self._court_to_image, self._scale, name,
                                     self._last_status.get(name)), jpeg)
                    jpeg = None
            if self._stop.is_set():
                self.state = "stopped"
        except Exception as exc:  # a camera failure must not take the gateway down; it is logged and the thread ends
            self.state, self.error = "failed", f"{type(exc).__name__}: {exc}"
            log.exception("camera thread failed")
