"""Frame sources: one interface for a live V4L2 camera, a video file, and the synthetic court camera.

Every frame carries ``t_host_s``: host monotonic seconds at which the image was *exposed* (best estimate), which
is the clock the gateway maps every IMU stream into. A source returns ``None`` at the end of the stream.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator, Protocol

import cv2
import numpy as np

from gateway.camera.errors import FrameSourceError


@dataclass(frozen=True)
class Frame:
    """One camera image: ``index`` counts frames the source produced (dropped ones leave gaps), ``image`` is BGR
    uint8 (H, W, 3), ``t_host_s`` host monotonic seconds, ``truth`` ground truth (synthetic sources only)."""

    index: int
    t_host_s: float
    image: np.ndarray
    truth: Any = None


class FrameSource(Protocol):
    """What the tracker and the gateway daemon consume."""

    image_size: tuple[int, int]  # (width_px, height_px)
    nominal_fps: float

    def read(self) -> Frame | None: ...

    def close(self) -> None: ...


class _IterableSource:
    """Iteration and context-manager sugar shared by the sources."""

    def read(self) -> Frame | None:  # pragma: no cover - overridden
        raise NotImplementedError

    def close(self) -> None:
        """Release the device or file (idempotent)."""

    def __iter__(self) -> Iterator[Frame]:
        while (frame := self.read()) is not None:
            yield frame

    def __enter__(self) -> "_IterableSource":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class VideoFileSource(_IterableSource):
    """Frames of a recorded clip with container timestamps mapped onto the host clock.

    ``t_host_s = t0_host_s + PTS``. OpenCV's ``CAP_PROP_POS_MSEC`` after ``read()`` is the PTS of the frame just
    read; it has returned 0 for every frame on some backends (opencv#8763), so when it stops increasing we fall
    back to ``index / fps``."""

    def __init__(self, path: str | Path, t0_host_s: float = 0.0) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise FrameSourceError(str(self.path), "no such video file")
        # one decoding thread: frame threading spent ~0.3 ms more CPU per 640x360 frame on hand-offs when paced like
        # a live camera, and the tracker, not the decoder, bounds the frame rate
        self._cap = cv2.VideoCapture(str(self.path), cv2.CAP_ANY, [cv2.CAP_PROP_N_THREADS, 1])
        if not self._cap.isOpened():
            raise FrameSourceError(str(self.path), "OpenCV cannot open this file as video")
        self.nominal_fps = float(self._cap.get(cv2.CAP_PROP_FPS)) or 30.0
        self.image_size = (int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        self.t0_host_s = t0_host_s
        self._index = 0
        self._last_pts_s = -1.0

    def read(self) -> Frame | None:
        ok, image = self._cap.read()
        if not ok:
            return None
        pts_s = self._cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
        if self._index > 0 and pts_s <= self._last_pts_s:
            pts_s = self._index / self.nominal_fps
        self._last_pts_s = pts_s
        frame = Frame(self._index, self.t0_host_s + pts_s, image)
        self._index += 1
        return frame

    def rewind(self) -> None:
        """Back to the first frame (a looping demo court); indices and times start again from 0."""
        self._cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
        self._index = 0
        self._last_pts_s = -1.0

    def close(self) -> None:
        self._cap.release()


class OpenCVCamera(_IterableSource):
    """A live camera through ``cv2.VideoCapture`` (V4L2 index such as ``0`` or a device path).

    The timestamp is ``time.monotonic()`` right after ``grab()`` minus ``latency_s`` (exposure + transfer delay,
    measured with the IMU-camera lag check). Driver timestamps are not used: they are unreliable across OpenCV
    releases and backends (opencv#8763, #15749). Needs hardware, so it is kept thin."""

    def __init__(
        self, device: int | str = 0, *, width: int | None = None, height: int | None = None,
        fps: float | None = None, latency_s: float = 0.0,
    ) -> None:
        self.device = device
        # OpenCV's own warnings for a camera that is not there ("can't open camera by index") would add two
        # stderr lines to our one-line refusal: quiet them for the open only
        level = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
        try:
            self._cap = cv2.VideoCapture(device, cv2.CAP_V4L2) if isinstance(device, int) else cv2.VideoCapture(device)
        finally:
            cv2.utils.logging.setLogLevel(level)
        if not self._cap.isOpened():
            raise FrameSourceError(f"camera {device!r}", "cannot open (not connected, busy, or no permission?)")
        requested = ((cv2.CAP_PROP_FRAME_WIDTH, width), (cv2.CAP_PROP_FRAME_HEIGHT, height), (cv2.CAP_PROP_FPS, fps))
        for prop, value in requested:
            if value is not None:
                self._cap.set(prop, value)
        self.nominal_fps = float(self._cap.get(cv2.CAP_PROP_FPS)) or 30.0
        self.image_size = (int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        self.latency_s = latency_s
        self._index = 0
        self.failed_reads = 0

    def read(self) -> Frame | None:
        if not self._cap.grab():
            self.failed_reads += 1
            return None
        t_host_s = time.monotonic() - self.latency_s
        ok, image = self._cap.retrieve()
        if not ok:
            self.failed_reads += 1
            return None
        frame = Frame(self._index, t_host_s, image)
        self._index += 1
        return frame

    def close(self) -> None:
        self._cap.release()
