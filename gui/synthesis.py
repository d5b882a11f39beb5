"""Windowed (fixed-lag) synthesis off the GUI thread.

The worker thread owns the synthesizer (`engine.graph.FixedLagSynthesizer` in the console): it takes sample
batches from a queue (fed by the bridge on the network thread), resamples them to the graph rate, pushes each
frame with the latest camera position/heading, and publishes the newest emitted pose in a lock-protected slot
that the GUI tick reads. Changing the lag rebuilds the synthesizer inside the worker thread."""
from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from gui.resample import FrameResampler


_RESET = object()
SensorKey = tuple[str, int]  # (station id, sensor index), as the gateway names streams


class Synthesizer(Protocol):
    def push(self, acc_g: np.ndarray, pos_m: np.ndarray | None = None, heading_rad: float | None = None) -> list: ...


@dataclass
class PoseOut:
    """Newest synthesized pose: ``t_s`` is the gateway-clock time the pose describes (frame time - lag)."""

    t_s: float
    positions_m: np.ndarray  # (J, 3) world frame
    emitted_at_s: float      # gateway-clock time of the frame whose push emitted it


@dataclass
class SynthesisStats:
    lag_s: float = 0.0
    frames_in: int = 0
    poses_out: int = 0
    frames_per_s: float = 0.0      # graph frames processed per wall second (recent)
    push_ms: float = 0.0           # mean synthesizer cost per frame (recent)
    frames_invalid: int = 0        # frames stepped without accelerations (a sensor dropped out)
    error: str = ""


def pose_positions(pose: Any) -> np.ndarray:
    """Joint positions (J, 3) from an emitted pose object (``joint_positions_m``, as `engine.graph.online.EmittedPose`) or a bare array."""
    return np.asarray(getattr(pose, "joint_positions_m", pose), float)


class SynthesisWorker(threading.Thread):
    """Background thread: sample batches in, newest pose out."""

    def __init__(self, make_synthesizer: Callable[[float], Synthesizer], sensors: Sequence[Hashable],
                 rate_hz: float, lag_s: float) -> None:
        super().__init__(name="console-synthesis", daemon=True)
        self._make = make_synthesizer
        self.sensors = list(sensors)
        self.rate_hz = rate_hz
        self._inbox: queue.SimpleQueue = queue.SimpleQueue()
        self._stopping = threading.Event()
        self._lock = threading.Lock()
        self._pose: PoseOut | None = None
        self._requested_lag_s: float | None = lag_s
        self._camera: tuple[np.ndarray, float | None] | None = None
        self.stats = SynthesisStats(lag_s=lag_s)

    # -- inputs (any thread) -----------------------------------------------------------------------------------
    def add_samples(self, sensor: Hashable, t_s: np.ndarray, acc_g: np.ndarray) -> None:
        """Signature matches `gui.bridge.SampleSink`, so the bridge can feed the worker directly."""
        self._inbox.put((sensor, np.asarray(t_s, float), np.asarray(acc_g, float)))

    def set_camera(self, position_m: Any, heading_rad: float | None) -> None:
        with self._lock:
            self._camera = (np.asarray(position_m, float)[:2], heading_rad) if position_m is not None else None

    def set_lag(self, lag_s: float) -> None:
        with self._lock:
            self._requested_lag_s = float(lag_s)

    def reset(self) -> None:
        """Forget buffered samples and the synthesizer's window (playback seek / back to live)."""
        with self._lock:
            self._pose = None
            self._camera = None  # the old position belongs to the old time line; wait for a fresh fix
        self._inbox.put(_RESET)  # in-band, so batches queued after the reset are kept

    def stop(self) -> None:
        self._stopping.set()
        self._inbox.put(None)

    # -- outputs (any thread) ----------------------------------------------------------------------------------
    def latest_pose(self) -> PoseOut | None:
        with self._lock:
            return self._pose

    def _rebuild(self, lag_s: float) -> Synthesizer | None:
        try:
            synth = self._make(lag_s)
        except Exception as exc:  # a bad lag or graph must show in the status bar, not kill the thread
            self.stats.error = f"{type(exc).__name__}: {exc}"
            return None
        self.stats.lag_s, self.stats.error = lag_s, ""
        return synth

    # -- thread ------------------------------------------------------------------------------------------------
    def run(self) -> None:
        resampler = FrameResampler(self.sensors, self.rate_hz)
        synth: Synthesizer | None = None
        camera_seen = False
        window_t0, window_frames, window_cost = time.monotonic(), 0, 0.0
        while not self._stopping.is_set():
            with self._lock:
                lag, self._requested_lag_s = self._requested_lag_s, None
                camera = self._camera
            if lag is not None:
                synth = self._rebuild(lag) or synth
            if camera is not None and not camera_seen:
                # the search anchors its global path at the first sample's position: restart it on the first
                # camera fix, otherwise the path stays wherever dead reckoning from (0, 0) took it
                camera_seen = True
                synth = self._rebuild(self.stats.lag_s) or synth
            try:
                item = self._inbox.get(timeout=0.1)
            except queue.Empty:
                continue
            batch = [item]
            while True:  # take everything queued: one resample pass per wake-up
                try:
                    batch.append(self._inbox.get_nowait())
                except queue.Empty:
                    break
            for entry in batch:
                if entry is _RESET:
                    resampler = FrameResampler(self.sensors, self.rate_hz)
                    synth = self._rebuild(self.stats.lag_s)
                    camera_seen = False
                elif entry is not None:
                    resampler.add(*entry)
            times, frames, valid = resampler.frames()
            self.stats.frames_invalid = resampler.frames_invalid
            if synth is None or not len(times):
                continue
            pos, heading = camera if camera is not None else (None, None)
            t_cost = time.perf_counter()
            for t, acc, ok in zip(times, frames, valid):
                # a frame spanning a sensor dropout steps the search on the camera alone (acc None)
                emitted = synth.push(acc if ok else None, pos, heading)
                self.stats.frames_in += 1
                if emitted:
                    newest = emitted[-1]
                    pose = PoseOut(float(t) - self.stats.lag_s, pose_positions(newest), float(t))
                    with self._lock:
                        self._pose = pose
                    self.stats.poses_out += len(emitted)
            window_cost += time.perf_counter() - t_cost
            window_frames += len(times)
            now = time.monotonic()
            if now - window_t0 >= 1.0:
                self.stats.frames_per_s = window_frames / (now - window_t0)
                self.stats.push_ms = 1e3 * window_cost / max(1, window_frames)
                window_t0, window_frames, window_cost = now, 0, 0.0


@dataclass
class SynthesisSetup:
    """Everything the console needs to run windowed synthesis (built by `gui.engine_link`)."""

    make_synthesizer: Callable[[float], Any]  # lag_s -> object with push(acc (S,3), pos (2,)|None, heading|None)
    sensors: list[SensorKey]                  # live sensor feeding each graph sensor column, in order
    rate_hz: float
    parents: np.ndarray                       # skeleton parents of emitted poses
    lag_s: float = 0.5
    # The overhead tracker's heading is a rule (direction of travel when running, else facing the net), not a
    # measurement; feeding it as a constraint drags the path when the rule is wrong. Off unless trusted.
    use_camera_heading: bool = False
