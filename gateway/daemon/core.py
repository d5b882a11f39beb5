"""The gateway: station readers + one clock + recorder + streaming server, in one process (`Gateway`); the
command line that runs it is `gateway.daemon.cli`.

Data flow (why it is shaped like this): each `StationReader` thread calls `Gateway.on_samples` with a clock-mapped
block. That one call (a) appends the block to the recorder's unbounded queue when recording, and (b) publishes
it to clients through per-client bounded queues. Neither step touches the disk or a socket, so acquisition never
waits on a slow disk or a slow console, and display drops can never remove a recorded sample.

Hook points for gateway/camera and gateway/calibration (duck-typed, see docs/gateway.md "Hooks"):
* ``camera``: an object with ``start(sink)`` / ``stop()``; it calls ``sink(observation: dict, jpeg: bytes|None)``
  with at least ``t_host_s``, ``position_m`` ``[x, y]`` (court frame) and ``heading_rad``.
  Code that runs its own loop can instead call `Gateway.publish_camera` directly.
* ``calibration``: an object with ``handle(action, args) -> result`` and ``state() -> dict``; optionally
  ``on_samples(station, sensor, t_host_s, acc_g, quat_wxyz)`` to see every sample (``quat_wxyz`` (N, 4) the
  sensor's orientations, None when it streams none), or (one wizard per athlete, `gateway.calibration.athletes`)
  ``on_athlete_samples(athlete, station, sensor, t_host_s, acc_g, quat_wxyz)``. Its state is published when it
  changes.
* ``athletes``: a `gateway.athletes.AthleteMap`; every samples message then carries ``athlete`` (who wears the
  sensor; absent for a sensor nobody wears). Without one every sample is the default athlete's ("player").
"""
from __future__ import annotations

import logging
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

import firmware_protocol as fp
from gateway import auth, wire
from gateway.athletes import AthleteConfig, AthleteMap, athletes_info
from gateway.device_checks import I32_MAX, I32_MIN, command_int
from gateway.links import DiscoveredPort, Link, LinkError, discover_hid, discover_serial, open_link
from gateway.recorder import Recorder
from gateway.names import BadNameError, check_name
from gateway.server import RequestError, StreamServer
from gateway.station import SampleBlock, StationReader
from gateway.vendors import make_reader

if TYPE_CHECKING:
    import ssl

log = logging.getLogger("gateway")

DEFAULT_LISTEN = "127.0.0.1:7766"
DISCOVERY_INTERVAL_S = 2.0
STATION_COMMANDS = {
    "identify": fp.Opcode.IDENTIFY,
    "set_rate": fp.Opcode.SET_RATE,
    "set_range": fp.Opcode.SET_RANGE,
    "start": fp.Opcode.START_STREAMING,
    "stop": fp.Opcode.STOP_STREAMING,
    "hello": fp.Opcode.REQUEST_HELLO,
    "status": fp.Opcode.REQUEST_STATUS,
    "clock_sync": fp.Opcode.REQUEST_CLOCK_SYNC,
    "enter_calibration": fp.Opcode.ENTER_CALIBRATION,
    "leave_calibration": fp.Opcode.LEAVE_CALIBRATION,
}
# The integer argument each command takes, and its default.
COMMAND_VALUE_ARG = {"identify": ("duration_ms", 2000), "set_rate": ("rate_hz", None), "set_range": ("range_g", None)}


class Gateway:
    """Everything the daemon runs, usable in-process (tests, the demo) or from `main`."""

    def __init__(
        self,
        sources: list[str] | tuple[str, ...] = (),
        *,
        listen: tuple[str, int] = ("127.0.0.1", 7766),
        record_dir: str | Path = "recordings",
        open_link: Callable[[str], Link] = open_link,
        camera: Any = None,
        calibration: Any = None,
        status_interval_s: float = 1.0,
        clock_window_s: float = 60.0,
        lock_after_s: float = 30.0,
        reconnect_interval_s: float = 0.2,
        display_queue_frames: int = 2048,
        status_line: Callable[[str], None] | None = None,
        discover: bool | list[Callable[[], list[DiscoveredPort]]] = False,
        name: str = "courtside-gateway",
        secrets: auth.Secrets = auth.Secrets(),
        max_clients: int = 32,
        handshake_timeout_s: float = 5.0,
        tls: "ssl.SSLContext | None" = None,
        sample_sinks: tuple[Callable[[SampleBlock], None], ...] = (),
        athletes: AthleteMap | None = None,
        server_options: dict[str, Any] | None = None,  # more StreamServer limits (e.g. queue_budget_bytes)
    ):
        self.name = name
        self.athletes = athletes or AthleteMap([AthleteConfig()])
        self._station_serials: dict[str, int] = {}  # reader name -> serial from its HELLO (serial-addressed sensors)
        self.sample_sinks = tuple(sample_sinks)  # e.g. gateway.lsl.LslPublisher.on_block: every block, reader thread
        self.recorder = Recorder(record_dir, on_event=self._on_recorder_event)
        self.camera = camera
        self.calibration = calibration
        self.status_interval_s = status_interval_s
        self._status_line = status_line
        self._open_link = open_link
        self._reader_options = {"clock_window_s": clock_window_s, "lock_after_s": lock_after_s,
                                "reconnect_interval_s": reconnect_interval_s}
        self.readers: list[StationReader] = []
        self._readers_lock = threading.Lock()
        self._station_names: dict[StationReader, str] = {}  # names claimed at each link's first frame
        self.server = StreamServer(self.handle_request, host=listen[0], port=listen[1], hello=self._hello,
                                   display_queue_frames=display_queue_frames, secrets=secrets,
                                   max_clients=max_clients, handshake_timeout_s=handshake_timeout_s, name=name,
                                   tls=tls, **(server_options or {}))
        # discovery functions polled for hot-plugged stations (True = USB serial + HID by VID:PID)
        self.discoverers = [discover_serial, discover_hid] if discover is True else list(discover or [])
        self.samples_in = 0
        self.camera_frames = 0
        self._last_calibration_state: Any = None
        self._stop = threading.Event()
        self._status_thread = threading.Thread(target=self._status_loop, name="gw-status", daemon=True)
        for source in sources:
            self.add_station(source)

    # -- lifecycle --------------------------------------------------------------------------------------------
    @property
    def address(self) -> tuple[str, int]:
        return self.server.address

    def start(self) -> "Gateway":
        self.server.start()
        with self._readers_lock:
            for reader in self.readers:
                if reader._thread is None:
                    reader.start()
        if self.camera is not None:
            self.camera.start(self.publish_camera)
        self._status_thread.start()
        log.debug("gateway listening on %s:%d", *self.address)  # the command prints it (one line, with its auth mode)
        return self

    def stop(self) -> None:
        """Stop readers, finish any recording (flushed + fsynced), close clients."""
        self._stop.set()
        if self.camera is not None:
            self.camera.stop()
        with self._readers_lock:
            readers = list(self.readers)
        for reader in readers:
            reader.stop()
        if self.recorder.active:
            try:
                self.recorder.stop()
            except ValueError:  # a disk fault closed the take in between: it is closed either way
                pass
        if self._status_thread.is_alive():
            self._status_thread.join(timeout=2)
        self.server.close()

    def __enter__(self) -> "Gateway":
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def add_station(self, source: str, open_link: Callable[[str], Link] | None = None) -> StationReader:
        """Read another link (path or URL); starts at once if the gateway is running."""
        reader = make_reader(source, self, open_link=open_link or self._open_link, **self._reader_options)
        with self._readers_lock:
            self.readers.append(reader)
        if self._status_thread.is_alive():
            reader.start()
        return reader

    def claim_station_name(self, reader: StationReader, wanted: str) -> str:
        """The name ``reader`` records and streams under: ``wanted`` (``st<id>``) unless another link already has
        it; then ``<wanted>-dup<n>`` and an alarm, so both stations are recorded separately (issue 22)."""
        with self._readers_lock:
            taken = {name for other, name in self._station_names.items() if other is not reader}
            name, n = wanted, 2
            while name in taken:
                name, n = f"{wanted}-dup{n}", n + 1
            self._station_names[reader] = name
            holder = next((other.source for other, other_name in self._station_names.items()
                           if other_name == wanted and other is not reader), None)
        if name != wanted:
            self.publish_event("alarm", name, f"two base stations announce station id {wanted!r}: {holder} keeps "
                               f"{wanted!r}, {reader.source} is recorded as {name!r}; give each station its own "
                               "id", {"station_id": wanted, "renamed_to": name, "link": reader.source})
        return name

    def reader(self, station: str) -> StationReader:
        with self._readers_lock:
            for reader in self.readers:
                if station in (reader.name, reader.source):
                    return reader
        raise RequestError(f"no station {station!r}; known: {[r.name for r in self.readers]}")

    # -- data in (reader / camera threads) --------------------------------------------------------------------
    def on_samples(self, block: SampleBlock) -> None:
        self.samples_in += len(block.counter)
        header, arrays = block.header(), block.arrays()  # one samples message for the recording and clients
        athlete = self.athletes.athlete_of(block.station, block.sensor, self._station_serials.get(block.station))
        if athlete is not None:
            header["athlete"] = athlete
        if self.recorder.active:
            self.recorder.put_samples(block.station, block.sensor, arrays, header=header)
        self.server.publish("samples", header, arrays)
        per_athlete = getattr(self.calibration, "on_athlete_samples", None)
        on_samples = getattr(self.calibration, "on_samples", None)
        if per_athlete is not None:
            per_athlete(athlete, block.station, block.sensor, block.t_host_s, block.acc_g, block.quat_wxyz)
        elif on_samples is not None:
            on_samples(block.station, block.sensor, block.t_host_s, block.acc_g, block.quat_wxyz)
        for sink in self.sample_sinks:
            sink(block)

    def on_clock_point(self, station: str, epoch: int, raw_ticks: int, ticks: int, arrival_s: float,
                       tick_hz: float) -> None:
        """Record every clock-sync point (raw evidence for `gateway.recorder.realign_take`)."""
        if self.recorder.active:
            self.recorder.put_rows("clock_points", station, -1,
                                   {"raw_ticks": np.array([raw_ticks], np.uint32), "ticks": np.array([ticks], np.int64),
                                    "epoch": np.array([epoch], np.uint32), "arrival_s": np.array([arrival_s])},
                                   header={"tick_hz": tick_hz})

    def on_station_event(self, station: str, level: str, message: str, details: dict | None = None) -> None:
        serial = (details or {}).get("station_serial")
        if serial is not None:
            self._station_serials[station] = int(serial)
        self.publish_event(level, station, message, details)

    def _on_recorder_event(self, level: str, message: str) -> None:
        """Disk fault or backlog refusal (recorder writer thread): alarm every client, publish the new state."""
        self.publish_event(level, "recorder", message)
        self.server.publish("recording", self.recorder.state())

    def publish_event(self, level: str, source: str, message: str, details: dict | None = None) -> None:
        header = {"t_host_s": time.monotonic(), "level": level, "source": source, "message": message,
                  **(details or {})}
        getattr(log, "warning" if level in ("warning", "alarm") else "info")("%s: %s", source, message)
        self.server.publish("event", header)
        if self.recorder.active:
            self.recorder.put("event", header)

    def publish_camera(self, observation: dict[str, Any], jpeg: bytes | None = None) -> None:
        """Camera hook: one tracked observation (``t_host_s``, ``position_m`` [x, y], ``heading_rad`` ...)."""
        self.camera_frames += 1
        header = {k: _jsonable(v) for k, v in observation.items()}
        if self.recorder.active:
            self.recorder.put("camera", header)  # thumbnails are display-only; positions are recorded
        arrays = {"jpeg": np.frombuffer(jpeg, np.uint8)} if jpeg else None
        self.server.publish("camera", header, arrays)

    def publish_calibration_state(self) -> None:
        if self.calibration is None:
            return
        state = _jsonable(self.calibration.state())
        if state != self._last_calibration_state:
            self._last_calibration_state = state
            self.server.publish("calibration", {"state": state})
            if self.recorder.active:
                self.recorder.put("calibration", {"state": state})

    # -- status -----------------------------------------------------------------------------------------------
    def list_stations(self) -> list[dict[str, Any]]:
        with self._readers_lock:
            readers = list(self.readers)
        return [reader.status() for reader in readers]

    def status(self, role: str = auth.OPERATOR) -> dict[str, Any]:
        """One status snapshot. Viewers see how many clients are connected, not who (issue 12)."""
        clients = self.server.client_stats()
        status = {
            "t_host_s": time.monotonic(), "stations": self.list_stations(), "recording": self.recorder.state(),
            "samples_in": self.samples_in, "camera_frames": self.camera_frames, "n_clients": len(clients),
            "clients": [vars(c) for c in clients] if role == auth.OPERATOR else [],
        }
        health = getattr(self.camera, "health", None)
        if health is not None:
            status["camera"] = health()
        return status

    def _hello(self) -> dict[str, Any]:
        return {"gateway": self.name, "t_host_s": time.monotonic(), "stations": self.list_stations(),
                "athletes": self.athletes_info()}

    def athletes_info(self) -> list[dict[str, Any]]:
        """Who wears what (`gateway.athletes.athletes_info`)."""
        return athletes_info(self.athletes)

    def discover_stations(self) -> list[str]:
        """Hot-plug: add every base station found by USB VID:PID (serial and HID) that is not read yet.
        A station that disappears is handled by its reader (state "lost", reconnect when it is back)."""
        with self._readers_lock:
            known = {r.source for r in self.readers}
        added = []
        for port in [p for discoverer in self.discoverers for p in discoverer()]:
            if port.source not in known:
                self.add_station(port.source)
                self.publish_event("info", "discovery", f"found {port.transport} station {port.source} "
                                   f"(serial number {port.serial_number})")
                added.append(port.source)
        return added

    def _status_loop(self) -> None:
        last_discovery = 0.0
        while not self._stop.wait(self.status_interval_s):
            if self.discoverers and time.monotonic() - last_discovery >= DISCOVERY_INTERVAL_S:
                last_discovery = time.monotonic()
                self.discover_stations()
            status = self.status()
            self.server.publish("status", status, viewer_header={**status, "clients": []})
            self.server.publish("recording", status["recording"])
            if self.recorder.active:
                self.recorder.put("clock", {"stations": [{"station": s["station"], **s["clock"]}
                                                         for s in status["stations"]]})
            try:
                self.publish_calibration_state()
            except Exception:  # a calibration bug must not stop status reporting
                log.exception("calibration state failed")
            if self._status_line is not None:
                for line in format_status_lines(status):
                    self._status_line(line)

    # -- control requests (client reader threads) -------------------------------------------------------------
    def handle_request(self, action: str, args: dict[str, Any], role: str = auth.OPERATOR) -> Any:
        """Serve one control request. Network clients reach this only after the server checked ``role`` may
        make it (`gateway.auth.required_role`); in-process callers are operators."""
        if action == "ping":
            return {"t_host_s": time.monotonic()}
        if action == "list_stations":
            return self.list_stations()
        if action == "status":
            return self.status(role)
        if action == "start_recording":
            try:
                take = check_name(args.get("take"), "take name")
            except BadNameError as exc:
                raise RequestError(str(exc)) from None
            try:
                state = self.recorder.start(take, meta={"gateway": self.name, "stations": self.list_stations()})
            except ValueError as exc:
                raise RequestError(str(exc)) from exc
            self.server.publish("recording", state)
            self.publish_event("info", "recorder", f"recording take {take}")
            return state
        if action == "stop_recording":
            try:
                state = self.recorder.stop()
            except ValueError as exc:
                raise RequestError(str(exc)) from exc
            self.server.publish("recording", state)
            self.publish_event("info", "recorder", f"stopped take {state['take']}: {state['samples_written']} samples")
            return state
        if action == "station_command":
            return self._station_command(args)
        if action == "calibration":
            if self.calibration is None:
                raise RequestError("no calibration workflow attached to this gateway")
            result = self.calibration.handle(str(args.get("action")), dict(args.get("args") or {}))
            self.publish_calibration_state()
            return _jsonable(result)
        raise RequestError(f"unknown action {action!r}; valid: {list(wire.ACTIONS)}")

    def _station_command(self, args: dict[str, Any]) -> dict[str, Any]:
        reader = self.reader(str(args.get("station")))
        command = args.get("command")
        if command not in STATION_COMMANDS:
            raise RequestError(f"unknown station command {command!r}; valid: {sorted(STATION_COMMANDS)}")
        extra = dict(args.get("args") or {})
        value = 0
        try:  # the wire fields are u8 sensor and i32 value: refuse what does not fit, naming the argument
            target = command_int("sensor", extra.get("sensor", fp.BROADCAST_SENSOR), 0, 255)
            if command in COMMAND_VALUE_ARG:
                key, default = COMMAND_VALUE_ARG[command]
                if extra.get(key, default) is None:
                    raise RequestError(f"{command} needs '{key}'")
                value = command_int(key, extra.get(key, default), I32_MIN, I32_MAX)
        except ValueError as exc:
            raise RequestError(f"{command}: {exc}") from None
        try:
            result = reader.command(STATION_COMMANDS[command], target=target, value=value)
        except (LinkError, TimeoutError) as exc:
            raise RequestError(str(exc)) from exc
        return {"station": reader.name, "command": command, **result}


def _jsonable(value: Any) -> Any:
    """numpy scalars/arrays -> plain JSON types (observations and calibration states may carry numpy)."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def format_status_lines(status: dict[str, Any]) -> list[str]:
    """Human status lines, one per station (what `courtside gateway` prints every second)."""
    lines = []
    for st in status["stations"]:
        sensors = st["sensors"]
        rate = sum(s["rate_hz"] for s in sensors)
        received = sum(s["received"] for s in sensors)
        lost = sum(s["lost"] for s in sensors)
        loss = 100.0 * lost / (received + lost) if received + lost else 0.0
        clock = st["clock"]
        offset = clock.get("offset_s")
        residual = clock.get("residual_s")
        lines.append(
            f"{st['station']:>8} {st['link']:<10} {len(sensors)} sensors {rate:7.1f} samples/s "
            f"loss {loss:5.2f}% crc {st.get('crc_errors', 0):4d} reconnects {st['reconnects']:2d} "
            f"offset {'%+.6f s' % offset if offset is not None else '   n/a'} "
            f"skew {clock.get('skew_ppm', 0.0):+7.2f} ppm "
            f"residual {'%.2f ms' % (residual * 1e3) if residual is not None else 'n/a'}"
            f"{'' if clock.get('locked') else ' (warming up)'}"
        )
    camera = status.get("camera")
    if camera:
        confidence = camera.get("confidence")
        lines.append(
            f"  camera {camera['state']:<8} {camera['fps']:5.1f} fps ({camera['nominal_fps']:.0f} nominal) "
            f"frames {camera['frames']} dropped {camera['dropped']} "
            + (f"tracking, confidence {confidence:.2f}" if confidence is not None else "not tracking")
            + (f" error: {camera['error']}" if camera.get("error") else ""))
    rec = status["recording"]
    if rec.get("active"):
        lines.append(f"recording {rec['take']}: {rec['samples_written']} samples, {rec['bytes_written']} bytes")
    return lines
