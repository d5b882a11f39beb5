"""Bridge between a `gateway.client.GatewayClient` (reader thread) and the console's GUI thread.

The client calls our listeners on its network thread. Listeners only copy data into thread-safe holders
(a queue for samples, a lock-protected "latest" slot for status/camera/calibration/recording, a queue for
events); the GUI thread's refresh tick reads them. Nothing here touches Qt, so a slow GUI can never block
the network side and the network side can never call into a widget from the wrong thread."""
from __future__ import annotations

import collections
import queue
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from gui.ringbuffer import TraceStore
from gui.synthesis import SensorKey
SampleSink = Callable[[SensorKey, np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None], None]
"""(sensor, t_host_s, acc_g, quat_wxyz or None, gyro_rps or None): the channels the sensor streams."""
CameraSink = Callable[[float, Any, "float | None"], None]  # (t_host_s, position_m [x, y] or None, heading_rad)


def gateway_clock_offset_s(client: Any, pings: int = 3) -> float:
    """Gateway clock minus local ``time.monotonic()`` (s), from the ping with the shortest round trip.

    Lets the console show sample ages and recording durations on the gateway's clock even when the gateway
    runs on another machine (same host: ~0). Called once at connect, before the GUI loop runs."""
    best: tuple[float, float] | None = None
    for _ in range(pings):
        t_send = time.monotonic()
        t_gateway = float(client.request("ping", timeout_s=2.0)["t_host_s"])
        t_recv = time.monotonic()
        if best is None or t_recv - t_send < best[0]:
            best = (t_recv - t_send, t_gateway - (t_send + t_recv) / 2)
    return best[1]


def client_local_address(client: Any) -> str | None:
    """``host:port`` of the client's end of the connection, as the gateway names it in ``status["clients"]``."""
    sock = getattr(client, "_sock", None)
    sock = getattr(sock, "sock", sock)  # a gateway.tls.TlsChannel wraps the socket
    try:
        host, port = sock.getsockname()[:2]
    except (AttributeError, OSError):
        return None
    return f"{host}:{port}"


class CameraRate:
    """Camera frame rate (EMA over observation times) and dropped frames (gaps in ``frame_index``), counted on
    every camera message as it arrives — the GUI only ever sees the latest one. A frame index that goes back is
    a source that started again (a looping court video, a camera reopened), not -N frames."""

    def __init__(self) -> None:
        self.fps = 0.0
        self.dropped = 0
        self._last: tuple[float, int | None] | None = None

    def add(self, t_s: float | None, frame_index: int | None) -> None:
        if t_s is None:
            return
        if self._last is not None:
            t_prev, i_prev = self._last
            if frame_index is not None and i_prev is not None and frame_index <= i_prev:
                i_prev = frame_index - 1  # the source started again (a looping file, a reopened camera): one frame
            if t_s > t_prev:
                frames = (frame_index - i_prev) if frame_index is not None and i_prev is not None else 1
                rate = frames / (t_s - t_prev)
                self.fps = rate if self.fps == 0 else 0.9 * self.fps + 0.1 * rate
            if frame_index is not None and i_prev is not None and frame_index > i_prev + 1:
                self.dropped += frame_index - i_prev - 1
        self._last = (t_s, frame_index)


class GatewayBridge:
    """Thread-safe landing zone for everything the gateway streams to the console."""

    TRAIL_LEN = 300  # camera positions kept for the minimap trail

    def __init__(self, traces: TraceStore) -> None:
        self.traces = traces
        self._lock = threading.Lock()
        self._latest: dict[str, dict[str, Any]] = {}
        self._jpeg: bytes | None = None
        self._trail: collections.deque[tuple[float, float, float]] = collections.deque(maxlen=self.TRAIL_LEN)
        self.events: queue.SimpleQueue[dict[str, Any]] = queue.SimpleQueue()
        self.sample_sinks: list[SampleSink] = []
        self.camera_sinks: list[CameraSink] = []  # every camera observation, in stream order (synthesis)
        # two athletes: each athlete's observations go only to its own sinks (its synthesis), never to another's;
        # ``camera_sinks`` then see the first athlete's (``camera_athlete``) only
        self.athlete_camera_sinks: dict[str, list[CameraSink]] = {}
        self.camera_athlete: str | None = None  # set by the first observation that names an athlete
        self.athlete_cameras: dict[str, dict[str, Any]] = {}  # athlete -> newest observation
        self._athlete_trails: dict[str, collections.deque] = {}
        self.sensor_athletes: dict[SensorKey, str] = {}  # who wears each sensor (samples' ``athlete``)
        self.recording_sinks: list[Callable[[float], None]] = []  # started_t_host_s of each new take
        self._take_started_s: float | None = None
        self._local_address: str | None = None
        self.display_dropped: dict[str, int] = {}  # our connection(s) -> display frames the gateway dropped for us
        self.camera_rate = CameraRate()
        self.samples_received = 0
        self.sensors_seen: dict[SensorKey, float] = {}  # sensor -> nominal rate (Hz)
        self.client = None

    # -- wiring -------------------------------------------------------------------------------------------------
    def attach(self, client: Any, topics: tuple[str, ...] = ("samples", "status", "camera", "calibration",
                                                               "recording", "event")) -> None:
        """Register listeners on a connected GatewayClient and subscribe to ``topics``."""
        self.client = client
        self._local_address = client_local_address(client)
        client.add_listener("samples", self.on_samples)
        for kind in ("status", "calibration", "recording"):
            client.add_listener(kind, self._on_latest)
        client.add_listener("camera", self.on_camera)
        client.add_listener("event", self.on_event)
        client.subscribe(list(topics))
        hello = getattr(client, "server_hello", {}) or {}
        if hello.get("stations"):
            with self._lock:
                self._latest["status"] = {"t_host_s": hello.get("t_host_s"), "stations": hello["stations"]}

    def detach(self) -> None:
        if self.client is None:
            return
        self.client.remove_listener("samples", self.on_samples)
        for kind in ("status", "calibration", "recording"):
            self.client.remove_listener(kind, self._on_latest)
        self.client.remove_listener("camera", self.on_camera)
        self.client.remove_listener("event", self.on_event)
        self.client = None

    # -- listeners (network thread) -------------------------------------------------------------------------
    def on_samples(self, msg: Any) -> None:
        key = (str(msg["station"]), int(msg["sensor"]))
        t, acc = msg["t_host_s"], msg["acc_g"]
        quat, gyro = msg.arrays.get("quat_wxyz"), msg.arrays.get("gyro_rps")
        self.sensors_seen[key] = float(msg.header.get("nominal_hz", 0.0))
        athlete = msg.header.get("athlete")
        if athlete is not None and key not in self.sensor_athletes:
            self.sensor_athletes[key] = str(athlete)
        self.samples_received += len(t)
        self.traces.put(key, t, acc, quat, gyro)
        for sink in self.sample_sinks:
            sink(key, t, acc, quat, gyro)

    def _on_latest(self, msg: Any) -> None:
        self.set_latest(msg.kind, msg.header)
        if msg.kind == "recording":
            self.note_recording(msg.header)
        elif msg.kind == "status":
            self._note_drops(msg.header)

    def _note_drops(self, status: dict[str, Any]) -> None:
        """Display frames the gateway dropped for this console (it drops oldest-first for a client that falls
        behind): live synthesis then saw less than the recorder wrote, so live and offline poses may differ."""
        for entry in status.get("clients") or []:
            if entry.get("address") == self._local_address and self._local_address is not None:
                self.display_dropped[self._local_address] = int(entry.get("dropped", 0))

    @property
    def dropped_total(self) -> int:
        return sum(self.display_dropped.values())

    def note_recording(self, state: dict[str, Any]) -> None:
        """A recording state (broadcast or request reply): tell the recording sinks once per new take."""
        started = state.get("started_t_host_s") if state.get("active") else None
        if started is not None and started != self._take_started_s:
            self._take_started_s = started
            for sink in self.recording_sinks:
                sink(float(started))

    def set_latest(self, kind: str, header: dict[str, Any]) -> None:
        """Store the newest header of ``kind`` (also used for request replies that carry the same state)."""
        with self._lock:
            self._latest[kind] = dict(header)

    def on_camera(self, msg: Any) -> None:
        header = dict(msg.header)
        athlete = header.get("athlete")
        with self._lock:
            if athlete is not None and self.camera_athlete is None:
                self.camera_athlete = str(athlete)
            first = athlete is None or athlete == self.camera_athlete
            pos = header.get("position_m")
            if athlete is not None:
                self.athlete_cameras[str(athlete)] = header
                trail = self._athlete_trails.setdefault(str(athlete), collections.deque(maxlen=self.TRAIL_LEN))
                if pos is not None:
                    trail.append((float(header.get("t_host_s", 0.0)), float(pos[0]), float(pos[1])))
            if "jpeg" in msg.arrays:
                self._jpeg = bytes(np.asarray(msg.arrays["jpeg"]).tobytes())
            if first:  # one observation per frame for the frame rate, the overlay's header and the trail
                self.camera_rate.add(header.get("t_host_s"), header.get("frame_index"))
                self._latest["camera"] = header
                if pos is not None:
                    self._trail.append((float(header.get("t_host_s", 0.0)), float(pos[0]), float(pos[1])))
        if header.get("t_host_s") is not None:
            fix = (float(header["t_host_s"]), header.get("position_m"), header.get("heading_rad"))
            for sink in self.athlete_camera_sinks.get(str(athlete), []) if athlete is not None else []:
                sink(*fix)
            if first:
                for sink in self.camera_sinks:
                    sink(*fix)

    def on_event(self, msg: Any) -> None:
        header = dict(msg.header)
        self.events.put(header)
        self.traces.put_event(float(header.get("t_host_s", 0.0)), str(header.get("message", ""))[:24])

    def reset_history(self) -> None:
        """Forget buffered traces, event markers, the camera trail and fix (playback seek / back to live)."""
        self.traces.rings.clear()
        self.traces.events.clear()
        with self._lock:
            self._trail.clear()
            self._athlete_trails.clear()
            self.athlete_cameras.clear()
            self.camera_rate = CameraRate()
            self._latest.pop("camera", None)  # a fix from the old time line must not anchor the new one

    # -- reads (GUI thread) -------------------------------------------------------------------------------------
    def latest(self, kind: str) -> dict[str, Any] | None:
        """Most recent header of ``kind`` (status, camera, calibration, recording), or None."""
        with self._lock:
            return self._latest.get(kind)

    def camera_frame(self) -> tuple[dict[str, Any] | None, bytes | None, np.ndarray]:
        """(latest camera header, latest JPEG thumbnail bytes, trail (N, 3) [t_s, x_m, y_m])."""
        with self._lock:
            trail = np.array(self._trail, float).reshape(-1, 3)
            return self._latest.get("camera"), self._jpeg, trail

    def athlete_tracks(self) -> dict[str, tuple[dict[str, Any], np.ndarray]]:
        """Athlete -> (newest camera observation, trail (N, 3) [t_s, x_m, y_m]), for the minimap and overlay."""
        with self._lock:
            return {name: (header, np.array(self._athlete_trails.get(name, ()), float).reshape(-1, 3))
                    for name, header in self.athlete_cameras.items()}

    def drain_events(self) -> list[dict[str, Any]]:
        out = []
        while True:
            try:
                out.append(self.events.get_nowait())
            except queue.Empty:
                return out

    def sensor_groups(self) -> dict[str, list[SensorKey]]:
        """Sensors seen so far grouped by station, sorted (for the trace panel's selector); with athletes named in
        the samples, grouped per athlete first ("alice · station st1"), athletes in the order first seen."""
        groups: dict[str, list[SensorKey]] = collections.defaultdict(list)
        athletes = list(dict.fromkeys(self.sensor_athletes.values()))
        many = len(athletes) > 1
        order = lambda key: (athletes.index(self.sensor_athletes[key]) if key in self.sensor_athletes  # noqa: E731
                             else len(athletes), key)
        for key in sorted(self.sensors_seen, key=order):
            who = self.sensor_athletes.get(key) if many else None
            groups[f"{who} · station {key[0]}" if who else f"station {key[0]}"].append(key)
        return dict(groups)
