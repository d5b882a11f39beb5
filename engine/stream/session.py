"""`StreamSynthesis`: timestamped samples and camera fixes in, one pose per synthesis frame out — the one
sample -> frame -> pose path shared by the console's live worker and `courtside synthesize`.

Why a single object: live and offline synthesis of the same take must give the same poses. Both feed this class
(live: batch by batch as the gateway streams them; offline: the whole recorded take at once) and every decision
in it depends on timestamps, never on arrival: frames on the absolute clock (`engine.stream.frames`), the camera
fix of each frame's own time (`engine.stream.camera`), the engine pushed one frame at a time from a defined first
frame. Two conditions are physical, not algorithmic, and are stated where they apply: a sensor whose data reach
the console more than ``wait_s`` (1 s) behind the others, or a camera more than ``camera_wait_s`` (2 s) behind the
sensors, is treated as a dropout live (offline it is not) — waiting longer would freeze the display whenever a
device dies —, and a client that drops samples (the gateway drops display data for a client that falls behind)
sees less than the recorder wrote.

A take's synthesis starts at a frame fixed by the take itself: ``TAKE_START_MARGIN_S`` after the recorder's
``started_t_host_s`` (the recording meta and the live ``recording`` state both carry it). The margin lets every
sensor's first recorded batch arrive, so the take holds the samples bracketing the first frame's window."""
from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .camera import CameraTrack
from .engines import OnlineEngine
from .frames import _EPS as FRAME_TIME_EPS, FrameBatch, FrameResampler

TAKE_START_MARGIN_S = 0.5


@dataclass(frozen=True)
class FramePose:
    """The pose decided for frame ``frame`` (at ``t_s = frame / rate_hz`` on the gateway clock)."""

    frame: int
    t_s: float
    joint_positions_m: np.ndarray  # (J, 3) world frame (x, y up, z) m
    confidence: float | None = None  # the engine's per-frame confidence in [0, 1], when it reports one
    source: Any = field(default=None, compare=False, repr=False)  # the engine's own pose object (node, path...)
    root_m: np.ndarray | None = None  # (3,) m and (J, 4) local rotations (w, x, y, z): the decided pose the joint
    local_rotations: np.ndarray | None = None  # positions come from (engine.stream.decided), when it has one

    @classmethod
    def of(cls, frame: int, rate_hz: float, emitted: Any) -> "FramePose":
        """Frame ``frame``'s pose from an engine's emitted pose (`EnginePose` or the engine's own type)."""
        conf = getattr(emitted, "confidence", None)
        return cls(frame, frame / rate_hz, np.asarray(emitted.joint_positions_m, float),
                   None if conf is None else float(conf), emitted, getattr(emitted, "root_m", None),
                   getattr(emitted, "local_rotations", None))


@dataclass
class StreamStats:
    frames_in: int = 0          # frames pushed to the engine since the (re)start
    frames_invalid: int = 0     # ... of which without accelerations (a sensor dropout)
    frames_with_camera: int = 0  # ... of which with a camera position
    frames_with_orientation: int = 0  # ... of which with some sensor's orientation (a non-NaN quaternion)
    frames_with_gyro: int = 0  # ... of which with some sensor's angular rate
    poses_out: int = 0
    # data that arrived after the frames it belongs to were pushed (later than the waits): while both are 0 (and
    # the gateway dropped nothing for this client), these poses are exactly what offline synthesis of the take gives
    late_samples: int = 0
    late_fixes: int = 0

    @property
    def reproducible(self) -> bool:
        return self.late_samples == 0 and self.late_fixes == 0


def take_start_s(started_t_host_s: float) -> float:
    """Gateway time of a take's first synthesis frame (see the module doc)."""
    return float(started_t_host_s) + TAKE_START_MARGIN_S


class StreamSynthesis:
    """Samples per live sensor + camera fixes -> frames -> engine -> `FramePose`s.

    ``sensors[i]`` is the live stream feeding the engine's sensor column i. ``start_s`` (None: the first frame all
    sensors cover) fixes the first frame; `restart` starts a fresh engine from a new first frame."""

    def __init__(self, make_engine: Callable[[], OnlineEngine], sensors: Sequence[Hashable], rate_hz: float, *,
                 start_s: float | None = None, max_gap_s: float = 0.25, wait_s: float = 1.0,
                 camera_max_gap_s: float = 0.5, camera_wait_s: float = 2.0, use_camera_heading: bool = False) -> None:
        if camera_wait_s < camera_max_gap_s:
            raise ValueError(f"camera_wait_s {camera_wait_s} must be at least camera_max_gap_s {camera_max_gap_s}")
        self._make = make_engine
        self.rate_hz = float(rate_hz)
        self.sensors = list(sensors)
        self.use_camera_heading = use_camera_heading
        self.resampler = FrameResampler(self.sensors, rate_hz, max_gap_s, wait_s)
        self.camera = CameraTrack(camera_max_gap_s)
        self.camera_wait_s = camera_wait_s
        self.engine: OnlineEngine | None = None
        self.first_frame: int | None = None  # frame of the engine's push index 0
        self._t_pushed = -np.inf  # time of the last frame pushed
        self.stats = StreamStats()
        self.restart(start_s)

    # -- input ----------------------------------------------------------------------------------------------------
    def add_samples(self, sensor: Hashable, t_s: np.ndarray, acc_g: np.ndarray, quat_wxyz: np.ndarray | None = None,
                    gyro_rps: np.ndarray | None = None) -> None:
        self.resampler.add(sensor, t_s, acc_g, quat_wxyz, gyro_rps)
        self.stats.late_samples = self.resampler.late_samples

    def add_camera(self, t_s: float, position_m: Any, heading_rad: float | None = None) -> None:
        self.stats.late_fixes += int(t_s <= self._t_pushed)
        self.camera.add(t_s, position_m, heading_rad)

    def restart(self, start_s: float | None = None) -> None:
        """A fresh engine (e.g. after a lag change) whose first frame is the first at or after ``start_s``; up to
        ``history_s`` (2 s) of buffered data can be revisited. None: carry on from the next frame."""
        self.engine = self._make()
        self.first_frame = None
        self.stats = StreamStats()
        if start_s is not None:
            self.resampler.start_at(start_s)
            self._t_pushed = -np.inf

    # -- output ---------------------------------------------------------------------------------------------------
    def step(self, max_frames: int | None = None) -> list[FramePose]:
        """Push every frame that is complete now (at most ``max_frames``; the same frames come out however they
        are sliced); returns the poses the engine decided."""
        until = np.inf
        if not self.camera.empty and self.camera.newest_s >= self.resampler.newest_s - self.camera_wait_s:
            # a live camera holds frames back until the fix after them is in: strictly after, so a frame on (or,
            # rounded, an ulp past) the newest fix waits for the next one; pushed now it would be interpolated
            # from the pair ending at that fix (or get none), offline from the pair starting at it
            until = self.camera.newest_s - 2 * FRAME_TIME_EPS / self.rate_hz
        return self.push_frames(self.resampler.frames(until, max_frames))

    @property
    def behind_s(self) -> float:
        """How far the last frame pushed trails the newest sample (s; 0 before the first frame). Live it stays
        near half a frame plus a batch while the engine keeps up, and grows without bound when the engine
        costs more per frame than a frame period (the console says so)."""
        newest = self.resampler.newest_s
        return max(0.0, newest - self._t_pushed) if np.isfinite(self._t_pushed) and np.isfinite(newest) else 0.0

    def finish(self) -> list[FramePose]:
        """End of input (offline): push what remains, then let the engine decide its pending frames.

        The take ends where all its streams end: a camera that was running at the end still holds back the
        frames after its last recorded fix (the recorder stops before the fixes of the last camera latency are
        published), exactly as live, where those frames got fixes the take does not have."""
        return self.step() + self._poses(self.engine.flush())

    def push_frames(self, batch: FrameBatch) -> list[FramePose]:
        if not len(batch):
            return []
        pos, head = self.camera.at(batch.t_s)
        poses: list[FramePose] = []
        for k in range(len(batch)):
            if self.first_frame is None:
                self.first_frame = int(batch.index[k])
            p = None if np.isnan(pos[k]).any() else pos[k]
            h = None if not self.use_camera_heading or np.isnan(head[k]) else float(head[k])
            channels = _channels(batch, k)
            poses += self._poses(self.engine.push(batch.acc_g[k] if batch.valid[k] else None, p, h, **channels))
            self.stats.frames_in += 1
            self.stats.frames_invalid += int(not batch.valid[k])
            self.stats.frames_with_camera += int(p is not None)
            self.stats.frames_with_orientation += int(channels["quat_wxyz"] is not None)
            self.stats.frames_with_gyro += int(channels["gyro_rps"] is not None)
        self._t_pushed = float(batch.t_s[-1])
        self.camera.trim_before(self._t_pushed)
        return poses

    def _poses(self, emitted: list[Any]) -> list[FramePose]:
        out = []
        for e in emitted:
            out.append(FramePose.of(self.first_frame + int(e.t), self.rate_hz, e))
        self.stats.poses_out += len(out)
        return out


def _channels(batch: FrameBatch, k: int) -> dict[str, np.ndarray | None]:
    """Frame k's ``quat_wxyz`` / ``gyro_rps`` keywords for `OnlineEngine.push`: None when the take does not
    stream the channel, on an invalid frame (a dropout, as for the accelerations) and when no sensor has a value
    (the rule `engine.stream.drive_frames` applies offline); else the (S, ...) row, NaN for sensors without."""
    out = {}
    for name in ("quat_wxyz", "gyro_rps"):
        values = getattr(batch, name)
        usable = values is not None and batch.valid[k] and not np.isnan(values[k]).all()
        out[name] = values[k] if usable else None
    return out


@dataclass
class RecordedStreams:
    """A take's raw inputs as the gateway recorded them: per live sensor (t_host_s (N,), acc_g (N, 3)[,
    quat_wxyz (N, 4) or None, gyro_rps (N, 3) or None]), camera fixes (t_host_s, position_m or None, heading_rad
    or None) in time order, and the recorder's start time."""

    samples: dict[Hashable, tuple[np.ndarray, ...]]
    camera: list[tuple[float, Any, float | None]] = field(default_factory=list)
    started_t_host_s: float | None = None


def synthesize_streams(make_engine: Callable[[], OnlineEngine], streams: RecordedStreams, sensors: Sequence[Hashable],
                       rate_hz: float, *, start_s: float | None = None, use_camera_heading: bool = False,
                       max_gap_s: float = 0.25, camera_max_gap_s: float = 0.5) -> tuple[list[FramePose], StreamSynthesis]:
    """Offline synthesis of a recorded take through the live path: every sample and fix fed at once, frames
    pushed from ``start_s`` (default: the take's defined first frame, `take_start_s`), then flushed."""
    if start_s is None and streams.started_t_host_s is not None:
        start_s = take_start_s(streams.started_t_host_s)
    session = StreamSynthesis(make_engine, sensors, rate_hz, start_s=start_s, max_gap_s=max_gap_s,
                              camera_max_gap_s=camera_max_gap_s, use_camera_heading=use_camera_heading)
    for key in sensors:
        session.add_samples(key, *streams.samples[key])
    for t, pos, heading in streams.camera:
        session.add_camera(t, pos, heading)
    return session.finish(), session
