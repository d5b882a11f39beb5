"""The gateway: station readers + one clock + recorder + streaming server, in-process (`Gateway`) or as a CLI.

Data flow (why it is shaped like this): each `StationReader` thread calls `Gateway.on_samples` with a clock-mapped
block. That one call (a) appends the block to the recorder's unbounded queue when recording, and (b) publishes
it to clients through per-client bounded queues. Neither step touches the disk or a socket, so acquisition never
waits on a slow disk or a slow console, and display drops can never remove a recorded sample.

Hook points for gateway/camera and gateway/calibration (duck-typed, see docs/gateway.md "Hooks"):
* ``camera``: an object with ``start(sink)`` / ``stop()``; it calls ``sink(observation: dict, jpeg: bytes|None)``
  with at least ``t_host_s``, ``position_m`` ``[x, y]`` (court frame) and ``heading_rad``.
  Code that runs its own loop can instead call `Gateway.publish_camera` directly.
* ``calibration``: an object with ``handle(action, args) -> result`` and ``state() -> dict``; optionally
  ``on_samples(station, sensor, t_host_s, acc_g)`` to see every sample, or (one wizard per athlete,
  `gateway.calibration.athletes`) ``on_athlete_samples(athlete, station, sensor, t_host_s, acc_g)``. Its state is
  published when it changes.
* ``athletes``: a `gateway.athletes.AthleteMap`; every samples message then carries ``athlete`` (who wears the
  sensor; absent for a sensor nobody wears). Without one every sample is the default athlete's ("player").
"""
from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

import firmware_protocol as fp
from engine.progress import add_quiet_argument
from gateway import auth, wire
from gateway.athletes import AthleteConfig, AthleteMap
from gateway.device_checks import I32_MAX, I32_MIN, command_int
from gateway.links import DiscoveredPort, Link, LinkError, discover_hid, discover_serial, open_link
from gateway.recorder import Recorder, export_take
from gateway.names import BadNameError, check_name
from gateway.server import RequestError, StreamServer
from gateway.station import SampleBlock, StationReader
from gateway.vendors import make_reader

if TYPE_CHECKING:
    import ssl

    from gateway.court_config import CourtConfig

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
        log.info("gateway listening on %s:%d", *self.address)
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
            per_athlete(athlete, block.station, block.sensor, block.t_host_s, block.acc_g)
        elif on_samples is not None:
            on_samples(block.station, block.sensor, block.t_host_s, block.acc_g)
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
        """Who wears what (consoles set up one synthesis per athlete from it): name, side, sensors
        (``"st1:0"`` / ``"sn<serial>:0"``; [] = every sensor), placements."""
        return [{"name": a.name, "side": a.side, "sensors": [str(r) for r in a.sensors],
                 "placements": list(a.placements)} for a in self.athletes.athletes]

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


# ---------------------------------------------------------------------------------------------------- CLI
EXIT_OK = 0  # stopped by SIGINT/SIGTERM or --duration: recording flushed and closed
EXIT_START_FAILED = 1  # could not start at run time (listen address in use, device gone): worth a restart
# exit 2: bad config, flag or file (a CourtsideError, printed as one line by gateway.cli); a restart cannot help

# command-line flag -> court config key (gateway.court_config); flags override the --config file
FLAG_KEYS = {
    "port": "stations.ports", "url": "stations.urls", "discover": "stations.discover", "emulate": "stations.emulate",
    "emulate_motion": "stations.emulate_motion", "emulate_clip": "stations.emulate_clips",
    "emulate_orientation": "stations.emulate_orientation",
    "camera": "camera.source", "court": "camera.court", "player_side": "camera.player_side",
    "camera_fps": "camera.fps", "camera_loop": "camera.loop", "placements": "calibration.placements",
    "pose": "calibration.pose", "calibration_dir": "calibration.records_dir", "record_dir": "record_dir",
    "record": "record", "listen": "listen", "log_level": "log_level", "secret_file": "auth.operator_secret_file",
    "viewer_secret_file": "auth.viewer_secret_file", "tls_cert": "auth.tls_cert", "tls_key": "auth.tls_key",
    "max_clients": "max_clients", "handshake_timeout": "handshake_timeout_s", "lsl": "lsl.enabled",
    "lsl_scope": "lsl.scope",
}


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="courtside gateway", description=__doc__.split("\n")[0],
        epilog="Every option can come from --config court.toml (keys in docs/gateway.md); options given here win. "
               "Also: courtside gateway export <take dir> [--npz F] [--csv-dir D] [--xdf F]; "
               "courtside gateway new-secret FILE. Exit codes: 0 stopped cleanly, 1 could not start "
               "(e.g. address in use), 2 bad config/arguments.")
    p.add_argument("--config", type=Path, help="court config TOML (stations, camera, calibration, auth, ...)")
    g = p.add_argument_group("stations")
    g.add_argument("--port", action="append", default=None, metavar="PATH",
                   help="serial port path, or hid:<path> / hid:VVVV:PPPP[:serial], or a device read through its "
                        "vendor's library: ximu3:<port>, shimmer:<port> (repeatable)")
    g.add_argument("--url", action="append", default=None, metavar="URL", help="pyserial URL, e.g. emu://... (repeatable)")
    g.add_argument("--discover", action=argparse.BooleanOptionalAction, default=None,
                   help="find stations by USB VID:PID 1209:C0DE (serial + HID), also hot-plugged ones")
    g.add_argument("--emulate", type=int, default=None, metavar="N", help="start N emulated stations over ptys")
    g.add_argument("--emulate-motion", default=None, metavar="mocap|none",
                   help="emulated sensors replay mocap clips (default) or stay still")
    g.add_argument("--emulate-clip", action="append", default=None, metavar="CLIP",
                   help="shipped clip name or .bvh/.amc file to replay (repeatable; default every shipped clip)")
    g.add_argument("--emulate-orientation", action=argparse.BooleanOptionalAction, default=None,
                   help="emulated sensors also stream orientation quaternions (realistic filter error: per-sensor "
                        "yaw, drift, tilt noise, misalignment) and angular rate (protocol v2)")
    g = p.add_argument_group("camera")
    g.add_argument("--camera", default=None, metavar="SRC", help="V4L2 index, device path or video file")
    g.add_argument("--court", type=Path, default=None, metavar="JSON",
                   help="court calibration (`courtside camera calibrate ... --out court.json`)")
    g.add_argument("--player-side", default=None, metavar="near|far", help="half the player starts on")
    g.add_argument("--camera-fps", type=float, default=None, help="frame rate asked of a live camera")
    g.add_argument("--camera-loop", action=argparse.BooleanOptionalAction, default=None,
                   help="play a video file again at its end")
    g = p.add_argument_group("calibration")
    g.add_argument("--placements", type=lambda text: [s.strip() for s in text.split(",") if s.strip()], default=None,
                   metavar="SITE,SITE,...", help="worn sensor sites: attaches the calibration wizard")
    g.add_argument("--pose", default=None, metavar="npose|tpose", help="calibration pose (default npose)")
    g.add_argument("--calibration-dir", type=Path, default=None, help="where calibration records are saved")
    g = p.add_argument_group("recording and network")
    g.add_argument("--record-dir", type=Path, default=None, help="where takes are written (default ./recordings)")
    g.add_argument("--record", metavar="TAKE", help="start recording this take at once (TAKE-2... if it exists)")
    g.add_argument("--listen", default=None, help=f"host:port for clients (default {DEFAULT_LISTEN}; beyond "
                   "loopback needs --secret-file)")
    g.add_argument("--secret-file", type=Path, default=None, help="operator secret (every client authenticates)")
    g.add_argument("--viewer-secret-file", type=Path, default=None, help="viewer secret (watch only)")
    g.add_argument("--tls-cert", type=Path, default=None, help="PEM certificate: serve TLS")
    g.add_argument("--tls-key", type=Path, default=None, help="PEM private key for --tls-cert")
    g.add_argument("--max-clients", type=int, default=None)
    g.add_argument("--handshake-timeout", type=float, default=None, metavar="S")
    g = p.add_argument_group("lab streaming layer")
    g.add_argument("--lsl", action="store_const", const=True, default=None,
                   help="publish one LSL outlet per station (pip install 'courtside[lsl]')")
    g.add_argument("--lsl-scope", default=None, help="machine (default: liblsl kept on 127.0.0.1) or network")
    p.add_argument("--duration", type=float, default=None, help="exit after this many seconds")
    p.add_argument("--quiet", action="store_true", help="no status lines")
    p.add_argument("--log-level", default=None, help="DEBUG, INFO (default), WARNING, ERROR")
    return p


def _export_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="courtside gateway export", description="Export a recording to npz and/or CSV")
    p.add_argument("recording", type=Path, help="take directory or its take.csrec")
    p.add_argument("--npz", type=Path, help="output .npz file")
    p.add_argument("--csv-dir", type=Path, help="output directory for CSV files")
    p.add_argument("--xdf", type=Path, help="output .xdf file (Lab Streaming Layer format, one stream per station)")
    add_quiet_argument(p)
    return p


def load_config(args: argparse.Namespace) -> "CourtConfig":
    """The court config file (or the defaults) with the command line's options applied on top."""
    from engine.errors import CourtsideError, MalformedFileError
    from gateway.court_config import CourtConfig, check_consistent, load_court_config, with_overrides

    config = load_court_config(args.config, check=False) if args.config else CourtConfig()
    overrides = {key: getattr(args, flag) for flag, key in FLAG_KEYS.items()}
    flags = {key: "--" + flag.replace("_", "-") for flag, key in FLAG_KEYS.items()}
    for key in ("record_dir", "calibration.records_dir", "camera.court", "auth.operator_secret_file",
                "auth.viewer_secret_file", "auth.tls_cert", "auth.tls_key"):
        if overrides[key] is not None:
            overrides[key] = str(overrides[key])
    given = {k: v for k, v in overrides.items() if v is not None}
    config = with_overrides(config, given, flags) if given else config
    try:  # the rules across keys, once the flags are in: a file-only problem names the file
        check_consistent(config)
    except CourtsideError as exc:
        if args.config and not given:
            raise MalformedFileError(args.config, None, str(exc)) from None
        raise
    return config


def _export_main(argv: list[str]) -> int:
    args = _export_parser().parse_args(argv)
    if not args.npz and not args.csv_dir and not args.xdf:
        print("courtside gateway export: give --npz, --csv-dir and/or --xdf", file=sys.stderr)
        return 2
    if args.npz or args.csv_dir:  # a bad recording raises RecordingError: the dispatcher reports it in one line
        for path in export_take(args.recording, args.npz, args.csv_dir):
            print(f"wrote {path}")
    if args.xdf:
        from gateway.xdf import export_xdf

        print(f"wrote {export_xdf(args.recording, args.xdf)}")
    return 0


def _new_secret_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="courtside gateway new-secret",
                                description="Write a new random secret to FILE (mode 600; never overwrites).")
    p.add_argument("file", type=Path)
    args = p.parse_args(argv)
    try:
        auth.write_secret_file(args.file)
    except OSError as exc:
        print(f"courtside gateway new-secret: {args.file}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    print(f"wrote {args.file} (copy it to each console machine, mode 600)")
    return 0


def _wait_for_stop(stop: threading.Event, duration_s: float | None, poll_s: float = 0.2) -> None:
    """Until ``stop`` is set or ``duration_s`` has passed, waking every ``poll_s``: a signal the kernel hands to
    another thread (any thread not blocking it may take it: liblsl's, a vendor driver's, or under a tracer) only
    runs its Python handler when the main thread next runs bytecode, which an untimed wait never does."""
    deadline = None if duration_s is None else time.monotonic() + duration_s
    while not stop.is_set():
        left = poll_s if deadline is None else min(poll_s, deadline - time.monotonic())
        if left <= 0:
            return
        stop.wait(left)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "export":
        return _export_main(argv[1:])
    if argv and argv[0] == "new-secret":
        return _new_secret_main(argv[1:])
    args = _parser().parse_args(argv)
    config = load_config(args)  # CourtsideError -> one line, exit 2 (gateway.cli)
    logging.basicConfig(level=config.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    from gateway.assembly import StartError, build_court

    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    printer = None if args.quiet else (lambda line: print(line, flush=True))
    try:
        court = build_court(config, status_line=printer)
    except StartError as exc:
        print(f"courtside gateway: cannot start: {exc}", file=sys.stderr)
        return EXIT_START_FAILED
    except OSError as exc:
        print(f"courtside gateway: cannot start: {exc.strerror or exc} (listen {config.listen[0]}:"
              f"{config.listen[1]})", file=sys.stderr)
        return EXIT_START_FAILED
    host, port = court.address
    mode = "authentication required" if config.authenticated else "no authentication: loopback only"
    if config.auth.tls_cert is not None:
        mode += ", TLS"
    print(f"gateway listening on {host}:{port} ({mode})", flush=True)
    if court.take:
        print(f"recording take {court.take}", flush=True)
    try:
        _wait_for_stop(stop, args.duration)
    finally:
        court.stop()
    print("gateway stopped", flush=True)
    return EXIT_OK
