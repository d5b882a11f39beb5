"""Live synthesis off the GUI thread: a thread around `engine.stream.StreamSynthesis`.

The bridge feeds sample batches and camera fixes (network thread) into an in-band queue; the worker thread owns
the stream session (resampling, camera alignment, the engine), publishes the newest pose in a lock-protected slot
the GUI tick reads, and — for unattended capture (`courtside console --save-poses`) — keeps every pose since the
last restart. All synthesis logic lives in the engine, so `courtside synthesize` on a recorded take runs the
same code. A recording start restarts the engine at the take's defined first frame
(`engine.stream.take_start_s`), so the poses shown during a take are exactly what offline synthesis of the take
gives; a lag change restarts it at the next frame; a reset (playback seek) starts a fresh session."""
from __future__ import annotations

import collections
import logging
import queue
import threading
import time
from collections.abc import Hashable
from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.stream import EngineSpec, FramePose, StreamSynthesis, take_start_s

SensorKey = tuple[str, int]  # (station id, sensor index), as the gateway names streams
log = logging.getLogger("courtside.console")
RECENT_POSES = 64  # poses a reader can still fetch after they were decided (`recent_poses`): 2 s at 30 Hz
BEHIND_WARN_S = 2.0  # synthesis this much beyond its lag behind the stream is reported as falling behind
_RESET = object()


@dataclass
class SynthesisSetup:
    """Everything the console needs to run live synthesis (`gui.engine_link.synthesis_setup`)."""

    engine: EngineSpec          # engine, database, worn placements, rate, skeleton
    sensors: list[SensorKey]    # live sensor feeding each engine sensor column, in order
    lag_s: float = 0.5
    # The overhead tracker's heading is a rule (direction of travel when running, else facing the net), not a
    # measurement; feeding it as a constraint drags the path when the rule is wrong. Off unless trusted.
    use_camera_heading: bool = False

    @property
    def parents(self) -> np.ndarray:
        return self.engine.parents


@dataclass
class SynthesisStats:
    lag_s: float = 0.0
    frames_in: int = 0
    poses_out: int = 0
    frames_per_s: float = 0.0      # frames processed per wall second (recent)
    push_ms: float = 0.0           # mean engine cost per frame (recent)
    frames_invalid: int = 0        # frames stepped without accelerations (a sensor dropped out)
    frames_with_camera: int = 0
    frames_with_orientation: int = 0  # frames pushed with some sensor's orientation / angular rate
    frames_with_gyro: int = 0
    late_samples: int = 0           # data that arrived after its frames were pushed (see engine.stream.StreamStats)
    late_fixes: int = 0
    start_frame: int | None = None  # first frame of the current session (engine restart)
    behind_s: float = 0.0           # newest sample minus the last frame pushed while complete frames wait for the
                                    # engine (engine.stream.StreamSynthesis.behind_s); 0 when nothing waits
    error: str = ""
    engine_status: str = ""         # what the engine says about itself live (e.g. a cheaper setting to keep up)

    def falling_behind(self, rate_hz: float) -> str:
        """A warning when synthesis trails the stream by more than its lag plus ``BEHIND_WARN_S`` (the engine
        costs more per frame than a frame period), naming the cost and the budget; else ""."""
        if self.behind_s <= self.lag_s + BEHIND_WARN_S:
            return ""
        budget_ms = 1e3 / rate_hz
        slower = f" ({self.push_ms / budget_ms:.1f}x slower than real time)" if self.push_ms > budget_ms else ""
        return (f"FALLING BEHIND: {self.behind_s:.1f} s behind the stream; the engine takes {self.push_ms:.0f} "
                f"ms/frame, real time needs < {budget_ms:.0f} ms{slower}")


class SynthesisWorker(threading.Thread):
    """Background thread: samples and camera fixes in, newest pose out (and optionally every pose)."""

    STEP_S = 0.5  # at most this much stream time of frames per pass (then the inbox and stats are served)

    def __init__(self, setup: SynthesisSetup, keep_poses: bool = False) -> None:
        super().__init__(name="console-synthesis", daemon=True)
        self.setup = setup
        self.keep_poses = keep_poses
        self._inbox: queue.SimpleQueue = queue.SimpleQueue()
        self._stopping = threading.Event()
        self._lock = threading.Lock()
        self._pose: FramePose | None = None
        self._poses: list[FramePose] = []
        self._poses_epoch = 0  # +1 whenever the kept poses start over (restart, reset): see `kept_poses_since`
        # the newest poses, numbered from 1 over the worker's life (never restarted), for a display that shows
        # every pose rather than the newest at each look (gui.pose_pacing)
        self._recent: collections.deque[tuple[int, FramePose]] = collections.deque(maxlen=RECENT_POSES)
        self._n_poses = 0
        self._lag_s = setup.lag_s
        self.stats = SynthesisStats(lag_s=setup.lag_s)
        self.fault = ""  # the interface of `gui.synthesis_process.SynthesisProcess`: a thread is never restarted
        self._worn = frozenset(setup.sensors)
        self._behind_logged = False

    # -- inputs (any thread) -----------------------------------------------------------------------------------
    def add_samples(self, sensor: Hashable, t_s: np.ndarray, acc_g: np.ndarray, quat_wxyz: np.ndarray | None = None,
                    gyro_rps: np.ndarray | None = None) -> None:
        """Signature matches `gui.bridge.SampleSink`, so the bridge can feed the worker directly; sensors the
        engine does not read are dropped here (the resampler would ignore them)."""
        if sensor not in self._worn:
            return
        self._inbox.put(("samples", sensor, np.asarray(t_s, float), np.asarray(acc_g, float), _floats(quat_wxyz),
                         _floats(gyro_rps)))

    def add_camera(self, t_s: float, position_m: Any, heading_rad: float | None) -> None:
        """One camera observation (gateway time of the camera frame; position None while the player is lost)."""
        self._inbox.put(("camera", float(t_s), position_m, heading_rad))

    def recording_started(self, started_t_host_s: float) -> None:
        """A take started: restart at its first frame, so the live poses are the take's offline poses."""
        self._inbox.put(("restart", take_start_s(started_t_host_s)))

    def set_lag(self, lag_s: float) -> None:
        self._inbox.put(("lag", float(lag_s)))

    def reset(self) -> None:
        """Forget buffered samples, fixes and the engine's window (playback seek / back to live)."""
        with self._lock:
            self._pose = None
        self._inbox.put(_RESET)  # in-band, so batches queued after the reset are kept

    def stop(self) -> None:
        self._stopping.set()
        self._inbox.put(None)

    # -- outputs (any thread) ----------------------------------------------------------------------------------
    def latest_pose(self) -> FramePose | None:
        with self._lock:
            return self._pose

    def poses(self) -> tuple[int | None, list[FramePose]]:
        """(first frame of the current session, every pose since) — with ``keep_poses`` only."""
        with self._lock:
            return self.stats.start_frame, list(self._poses)

    def recent_poses(self, after: int) -> list[tuple[int, FramePose]]:
        """(number, pose) of the recent poses numbered after `after` (at most the last RECENT_POSES)."""
        with self._lock:
            return [(n, pose) for n, pose in self._recent if n > after]

    def kept_poses_since(self, epoch: int, n_seen: int) -> tuple[int, int | None, list[FramePose]]:
        """(epoch, first frame of the session, the kept poses a reader has not seen): those after its `n_seen`
        while the kept list is still the one of its `epoch`, else all of them under the new epoch (the list
        started over). Lets a reader follow a long capture without copying the whole list each time."""
        with self._lock:
            if epoch != self._poses_epoch:
                n_seen = 0
            return self._poses_epoch, self.stats.start_frame, self._poses[n_seen:]

    # -- thread ------------------------------------------------------------------------------------------------
    def _new_session(self) -> StreamSynthesis | None:
        setup = self.setup
        try:
            return StreamSynthesis(lambda: setup.engine.live(self._lag_s), setup.sensors, setup.engine.rate_hz,
                                   use_camera_heading=setup.use_camera_heading)
        except Exception as exc:  # a bad lag or database must show in the athlete status, not kill the thread
            self.stats.error = f"{type(exc).__name__}: {exc}"
            return None

    def _restart(self, session: StreamSynthesis, start_s: float | None) -> None:
        try:
            session.restart(start_s)
        except Exception as exc:
            self.stats.error = f"{type(exc).__name__}: {exc}"
            return
        self.stats.lag_s, self.stats.error = self._lag_s, ""
        with self._lock:
            self._poses = []
            self._poses_epoch += 1
            self._pose = None

    def _handle(self, session: StreamSynthesis | None, entry: Any) -> StreamSynthesis | None:
        if entry is _RESET:
            with self._lock:
                self._poses = []
                self._poses_epoch += 1
            return self._new_session()
        if session is None or entry is None:
            return session
        kind = entry[0]
        if kind == "samples":
            session.add_samples(*entry[1:])
        elif kind == "camera":
            session.add_camera(*entry[1:])
        elif kind == "restart":
            self._restart(session, entry[1])
        elif kind == "lag":
            self._lag_s = entry[1]
            self._restart(session, None)
        return session

    def run(self) -> None:
        session = self._new_session()
        window_t0, window_frames, window_cost = time.monotonic(), 0, 0.0
        # frames pushed per pass: an engine slower than real time (OLNG on a small CPU) must not hold the queue,
        # the stats and the displayed pose for as long as a whole backlog takes; the frames are the same
        max_frames = max(1, int(round(self.setup.engine.rate_hz * self.STEP_S)))
        more = False  # the last pass stopped at max_frames: go on without waiting for new input
        while not self._stopping.is_set():
            batch = []
            try:
                batch.append(self._inbox.get_nowait() if more else self._inbox.get(timeout=0.1))
            except queue.Empty:
                if not more:
                    continue
            while True:  # take everything queued: one resampling pass per wake-up
                try:
                    batch.append(self._inbox.get_nowait())
                except queue.Empty:
                    break
            for entry in batch:
                session = self._handle(session, entry)
            more = False
            if session is None:
                continue
            t_cost = time.perf_counter()
            frames_before = session.stats.frames_in
            try:
                poses = session.step(max_frames)
            except Exception as exc:
                self.stats.error = f"{type(exc).__name__}: {exc}"
                continue
            window_cost += time.perf_counter() - t_cost
            window_frames += session.stats.frames_in - frames_before
            more = session.stats.frames_in - frames_before >= max_frames
            # behind only while complete frames wait for the engine: frames held back by the data (a sensor or
            # the camera waited for, a gateway restarting) are not the engine falling behind
            self.stats.behind_s = session.behind_s if more else 0.0
            s = session.stats
            self.stats.frames_in, self.stats.frames_invalid = s.frames_in, s.frames_invalid
            self.stats.frames_with_camera, self.stats.poses_out = s.frames_with_camera, s.poses_out
            self.stats.frames_with_orientation, self.stats.frames_with_gyro = s.frames_with_orientation, \
                s.frames_with_gyro
            self.stats.late_samples, self.stats.late_fixes = s.late_samples, s.late_fixes
            self.stats.start_frame = session.first_frame
            self._note_engine_status(getattr(session.engine, "status", ""))
            if poses:
                with self._lock:
                    self._pose = poses[-1]
                    self._recent.extend(enumerate(poses, self._n_poses + 1))
                    self._n_poses += len(poses)
                    if self.keep_poses:
                        self._poses.extend(poses)
            now = time.monotonic()
            if now - window_t0 >= 1.0:
                self.stats.frames_per_s = window_frames / (now - window_t0)
                self.stats.push_ms = 1e3 * window_cost / max(1, window_frames)
                window_t0, window_frames, window_cost = now, 0, 0.0
                self._log_falling_behind()

    def _note_engine_status(self, status: str) -> None:
        """Keep the engine's own status line for the athlete status, and log each change (unattended runs)."""
        if status != self.stats.engine_status:
            log.info("synthesis (%s): %s", self.setup.engine.label, status or "engine back to its full setting")
        self.stats.engine_status = status

    def _log_falling_behind(self) -> None:
        """One log line when synthesis starts falling behind (an unattended run has no status bar) and one when
        it has caught up again."""
        warning = self.stats.falling_behind(self.setup.engine.rate_hz)
        if warning and not self._behind_logged:
            log.warning("synthesis (%s): %s", self.setup.engine.label, warning)
        elif not warning and self._behind_logged:
            log.info("synthesis (%s) caught up with the stream", self.setup.engine.label)
        self._behind_logged = bool(warning)


def _floats(values: np.ndarray | None) -> np.ndarray | None:
    return None if values is None else np.asarray(values, float)
