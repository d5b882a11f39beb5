"""One court config: everything `courtside gateway` runs (stations, camera, calibration, recording, network,
authentication), read from a TOML file into frozen dataclasses whose field defaults are the only defaults.

Why strict: a service reads this file unattended, so a typo must stop it with one line naming the file, the key
and the problem, never start something else (issue 12 found ``ports = "/dev/ttyX"`` opening nine readers, one per
character, and ``discover = "no"`` meaning *on*). Every key is checked for its exact TOML type and range; unknown
keys and tables are refused. Command-line flags go through the same checks (`with_overrides`), naming the flag.

Relative paths in the file are resolved against the file's directory (a service's working directory is not the
operator's); relative paths given as flags against the current directory. Every key: docs/gateway.md "Config file".
"""
from __future__ import annotations

import ipaddress
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

from engine.errors import CourtsideError, MalformedFileError
from engine.safe_load import parse_toml, read_bytes
from gateway.athletes import DEFAULT_ATHLETE, AthleteConfig, SensorRef
from gateway.names import BadNameError, check_name

LOG_LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR")
EMULATE_MOTIONS = ("mocap", "none")
PLAYER_SIDES = ("near", "far")
POSES = ("npose", "tpose")
LSL_SCOPES = ("machine", "network")
MAX_EMULATED_STATIONS = 16
MIN_HANDSHAKE_TIMEOUT_S = 0.1  # a TLS + HMAC handshake on loopback takes ~10 ms; below this no client can finish
MIN_STATUS_INTERVAL_S = 0.05  # status is a full snapshot to every client: faster than 20 Hz only costs CPU


@dataclass(frozen=True)
class StationsConfig:
    """Base stations: explicit ports/URLs, USB discovery, and emulated stations (tests, demos, no hardware)."""

    ports: tuple[str, ...] = ()  # serial paths, or hid:<path> / hid:VVVV:PPPP[:serial]
    urls: tuple[str, ...] = ()  # pyserial URLs (emu://..., socket://...)
    discover: bool = False  # find stations by USB VID:PID 1209:C0DE, hot-plug included
    emulate: int = 0  # number of emulated stations on ptys
    emulate_motion: str = "mocap"  # what emulated sensors feel: "mocap" (clips below) or "none" (still + noise)
    emulate_clips: tuple[str, ...] = ()  # shipped clip names or .bvh/.amc paths; () = every shipped clip
    emulate_orientation: bool = False  # emulated sensors also stream orientation + angular rate (protocol v2)


@dataclass(frozen=True)
class CameraConfig:
    """The overhead camera; no ``source`` = no camera."""

    source: int | str | None = None  # V4L2 index, a device path (/dev/video0) or a video file
    court: Path | None = None  # court calibration JSON (`courtside camera calibrate --out court.json`)
    player_side: str | None = None  # half where the instrumented player starts: "near" / "far" / None = any
    fps: float | None = None  # frame rate asked of a live camera (files play at their own rate)
    latency_s: float = 0.0  # exposure + transfer delay subtracted from live frame times
    loop: bool = False  # video files: start again at the end (a demo court) instead of ending
    thumbnail_every: int = 10  # JPEG thumbnail for the console every N frames (0 = none)


@dataclass(frozen=True)
class CalibrationConfig:
    """The sensor-calibration wizard; attached when ``placements`` names the worn sensors."""

    placements: tuple[str, ...] = ()  # standard sensor sites (engine.mocap.STANDARD_SENSORS), the segment table
    pose: str = "npose"  # the pose the subject holds: "npose" (arms down) or "tpose"
    records_dir: Path = Path("calibrations")  # the only place saved records go


@dataclass(frozen=True)
class AuthConfig:
    """Who may connect. With an operator secret every client authenticates (HMAC challenge-response); without
    one the gateway listens on loopback only and every local client is an operator."""

    operator_secret_file: Path | None = None  # may record, command stations, calibrate
    viewer_secret_file: Path | None = None  # may only watch (streams, status)
    tls_cert: Path | None = None  # PEM certificate chain: serve TLS (needs tls_key)
    tls_key: Path | None = None  # PEM private key


@dataclass(frozen=True)
class LslConfig:
    """Lab Streaming Layer outlets (gateway.lsl), one per station."""

    enabled: bool = False
    scope: str = "machine"  # "machine": liblsl kept on 127.0.0.1 (lsl_api.cfg); "network": announce to the LAN


@dataclass(frozen=True)
class CourtConfig:
    """Everything one gateway runs. Build with `load_court_config` / `CourtConfig()` + `with_overrides`."""

    listen: tuple[str, int] = ("127.0.0.1", 7766)
    record_dir: Path = Path("recordings")
    record: str | None = None  # start recording this take at once (a new suffixed take if it exists)
    log_level: str = "INFO"
    name: str = "courtside-gateway"
    max_clients: int = 32
    handshake_timeout_s: float = 5.0  # a client must authenticate (and finish any frame it starts) this fast
    status_interval_s: float = 1.0
    clock_lock_after_s: float = 30.0  # clock warm-up before samples are flagged locked
    stations: StationsConfig = field(default_factory=StationsConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    calibration: CalibrationConfig = field(default_factory=CalibrationConfig)
    auth: AuthConfig = field(default_factory=AuthConfig)
    lsl: LslConfig = field(default_factory=LslConfig)
    athletes: tuple[AthleteConfig, ...] = ()  # [[athletes]]; () = one athlete "player" wearing every sensor

    @property
    def authenticated(self) -> bool:
        return self.auth.operator_secret_file is not None

    def effective_athletes(self) -> tuple[AthleteConfig, ...]:
        """The athletes this court runs: the ``[[athletes]]`` entries, or the single default athlete ("player",
        every sensor, ``camera.player_side``, ``calibration.placements``, ``stations.emulate_clips``)."""
        if self.athletes:
            return self.athletes
        return (AthleteConfig(DEFAULT_ATHLETE, self.camera.player_side, (), self.calibration.placements,
                              self.stations.emulate_clips),)


# -- value checks: each returns the converted value or raises _Bad(problem) -------------------------------------
class _Bad(Exception):
    pass


def _describe(value: Any) -> str:
    kind = {str: "a string", bool: "a boolean", int: "an integer", float: "a number", list: "a list",
            dict: "a table"}.get(type(value), type(value).__name__)
    shown = repr(value) if not isinstance(value, (list, dict)) else ""
    return f"{kind} {shown}".strip() if len(shown) < 60 else kind


def _string(value: Any) -> str:
    if not isinstance(value, str) or not value.strip():
        raise _Bad(f"expected a non-empty string, got {_describe(value)}")
    if "\x00" in value:  # TOML allows "\u0000"; the OS would refuse it later, naming neither file nor key
        raise _Bad("contains a NUL byte (\\u0000)")
    return value


def _bool(value: Any) -> bool:
    if not isinstance(value, bool):
        raise _Bad(f"expected true or false, got {_describe(value)}")
    return value


def _int(lo: int, hi: int) -> Callable[[Any], int]:
    def check(value: Any) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise _Bad(f"expected an integer {lo}..{hi}, got {_describe(value)}")
        if not lo <= value <= hi:
            raise _Bad(f"{value} is out of range {lo}..{hi}")
        return value
    return check


def _number(lo: float, hi: float, lo_open: bool = False) -> Callable[[Any], float]:
    low = f"{'>' if lo_open else '>='} {lo:g}"

    def check(value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _Bad(f"expected a number {low} and <= {hi:g}, got {_describe(value)}")
        value = float(value)
        if not math.isfinite(value) or value < lo or (lo_open and value == lo) or value > hi:
            raise _Bad(f"{value:g} is out of range ({low}, <= {hi:g})")
        return value
    return check


def _choice(options: tuple[str, ...]) -> Callable[[Any], str]:
    def check(value: Any) -> str:
        if not isinstance(value, str) or value not in options:
            raise _Bad(f"expected one of {', '.join(repr(o) for o in options)}, got {_describe(value)}")
        return value
    return check


def _upper_choice(options: tuple[str, ...]) -> Callable[[Any], str]:
    inner = _choice(options)
    return lambda value: inner(value.upper() if isinstance(value, str) else value)


def _strings(value: Any) -> tuple[str, ...]:
    if not isinstance(value, list):
        raise _Bad(f"expected a list of strings (e.g. [\"a\", \"b\"]), got {_describe(value)}")
    for i, item in enumerate(value):
        if not isinstance(item, str) or not item.strip():
            raise _Bad(f"item {i} is {_describe(item)}, expected a non-empty string")
        if "\x00" in item:
            raise _Bad(f"item {i} contains a NUL byte (\\u0000)")
    return tuple(value)


def _listen(value: Any) -> tuple[str, int]:
    if isinstance(value, tuple):  # already parsed (a default, or an override from code)
        value = f"{value[0]}:{value[1]}"
    text = _string(value)
    host, sep, port = text.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not re.fullmatch(r"\d{1,5}", port):
        raise _Bad(f"expected \"host:port\" (e.g. \"127.0.0.1:7766\"), got {text!r}")
    if int(port) > 65535:
        raise _Bad(f"port {port} is out of range 0..65535")
    return host, int(port)


def _camera_source(value: Any) -> int | str:
    if isinstance(value, str) and value.isdigit():
        value = int(value)  # "--camera 0" from the command line
    if isinstance(value, int) and not isinstance(value, bool):
        return _int(0, 63)(value)
    return _string(value)


def _placements(value: Any) -> tuple[str, ...]:
    from engine.mocap.sensors import STANDARD_SENSORS  # lazy: only configs with calibration pay for the engine

    names = _strings(value)
    unknown = [n for n in names if n not in STANDARD_SENSORS]
    if unknown:
        raise _Bad(f"unknown sensor site(s) {unknown}; known: {', '.join(STANDARD_SENSORS)}")
    if len(set(names)) != len(names):
        raise _Bad("a sensor site is listed twice")
    return names


def _sensor_refs(value: Any) -> tuple[SensorRef, ...]:
    refs = []
    for text in _strings(value):
        try:
            refs.append(SensorRef.parse(text))
        except ValueError as exc:
            raise _Bad(str(exc)) from None
    if len(set(refs)) != len(refs):
        raise _Bad("a sensor is listed twice")
    return tuple(refs)


def _athlete_name(value: Any) -> str:
    try:
        return check_name(value, "athlete name")
    except BadNameError as exc:
        raise _Bad(str(exc)) from None


def _take(value: Any) -> str:
    try:
        return check_name(value, "take name")
    except BadNameError as exc:
        raise _Bad(str(exc)) from None


_PATH = object()  # marker: a path, resolved against the config file's directory
_DIR = object()  # marker: a directory path, resolved like _PATH; if it exists it must be a directory
_CAMERA_SOURCE = object()  # marker: an index/device, or a video file path resolved like _PATH
_CLIPS = object()  # marker: clip names, or .bvh/.amc paths resolved like _PATH
Check = Callable[[Any], Any] | object
CLIP_SUFFIXES = (".bvh", ".amc")

_TOP: dict[str, Check] = {
    "listen": _listen, "record_dir": _DIR, "record": _take, "log_level": _upper_choice(LOG_LEVELS),
    "name": _string, "max_clients": _int(1, 1024),
    # durations and rates have physical bounds (issue 22: handshake_timeout_s = 1e-300 disconnected every client)
    "handshake_timeout_s": _number(MIN_HANDSHAKE_TIMEOUT_S, 600.0),
    "status_interval_s": _number(MIN_STATUS_INTERVAL_S, 60.0), "clock_lock_after_s": _number(0.0, 3600.0),
}
_SECTIONS: dict[str, tuple[type, dict[str, Check]]] = {
    "stations": (StationsConfig, {
        "ports": _strings, "urls": _strings, "discover": _bool, "emulate": _int(0, MAX_EMULATED_STATIONS),
        "emulate_motion": _choice(EMULATE_MOTIONS), "emulate_clips": _CLIPS,
        "emulate_orientation": _bool}),
    "camera": (CameraConfig, {
        "source": _CAMERA_SOURCE, "court": _PATH, "player_side": _choice(PLAYER_SIDES),
        "fps": _number(1.0, 1000.0), "latency_s": _number(0.0, 5.0), "loop": _bool,
        "thumbnail_every": _int(0, 10_000)}),
    "calibration": (CalibrationConfig, {"placements": _placements, "pose": _choice(POSES), "records_dir": _DIR}),
    "auth": (AuthConfig, {"operator_secret_file": _PATH, "viewer_secret_file": _PATH, "tls_cert": _PATH,
                          "tls_key": _PATH}),
    "lsl": (LslConfig, {"enabled": _bool, "scope": _choice(LSL_SCOPES)}),
}
_ATHLETE_KEYS: dict[str, Check] = {
    "name": _athlete_name, "side": _choice(PLAYER_SIDES), "sensors": _sensor_refs, "placements": _placements,
    "clips": _CLIPS}
_MOVED = {"ports": "stations", "urls": "stations", "discover": "stations", "emulate": "stations"}


def _resolve(path: Path, base_dir: Path | None) -> Path:
    path = path.expanduser()
    return path if path.is_absolute() or base_dir is None else base_dir / path


def _convert(check: Check, value: Any, base_dir: Path | None) -> Any:
    if check is _PATH or check is _DIR:
        path = _resolve(Path(_string(value if not isinstance(value, Path) else str(value))), base_dir)
        if check is _DIR and path.exists() and not path.is_dir():
            raise _Bad(f"{path} exists and is not a directory")
        return path
    if check is _CAMERA_SOURCE:  # a relative string is a video file next to the config (devices are absolute)
        source = _camera_source(value)
        return str(_resolve(Path(source), base_dir)) if isinstance(source, str) else source
    if check is _CLIPS:
        return tuple(str(_resolve(Path(c), base_dir)) if c.lower().endswith(CLIP_SUFFIXES) else c
                     for c in _strings(value))
    return check(value)  # type: ignore[operator]


def _line_of(text: str, section: str | None, key: str) -> int | None:
    """1-based line of ``key =`` in ``[section]`` (None = top level), for the error message; None if not found."""
    current = None
    for number, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        if header := re.fullmatch(r"\[\[?\s*([A-Za-z0-9_.-]+)\s*\]\]?\s*(#.*)?", stripped):
            current = header[1]
            if section is None and current == key:  # a table where a value belongs: point at its header
                return number
        elif current == section and re.match(rf"{re.escape(key)}\s*=", stripped):
            return number
    return None


def load_court_config(path: str | Path, check: bool = True) -> CourtConfig:
    """Read and check a court config file; `MalformedFileError` names the file, line, key and problem.
    ``check=False`` leaves the rules across keys to `with_overrides` (command-line flags may complete them)."""
    path = Path(path)
    try:
        text = read_bytes(path).decode("utf-8")
    except UnicodeDecodeError:
        raise MalformedFileError(path, None, "not a text (UTF-8 TOML) file") from None
    data = parse_toml(text, path)  # depth-safe (issue 22)
    base_dir = path.resolve().parent

    def fail(section: str | None, key: str, problem: str) -> MalformedFileError:
        name = f"{section}.{key}" if section else key
        return MalformedFileError(path, _line_of(text, section, key), f"{name}: {problem}")

    top: dict[str, Any] = {}
    sections: dict[str, Any] = {}
    for key, value in data.items():
        if key in _SECTIONS:
            if not isinstance(value, dict):
                raise fail(None, key, f"expected a [{key}] table, got {_describe(value)}")
            cls, checks = _SECTIONS[key]
            values = {}
            for sub, sub_value in value.items():
                if sub not in checks:
                    raise fail(key, sub, f"unknown key; [{key}] takes {', '.join(checks)}")
                try:
                    values[sub] = _convert(checks[sub], sub_value, base_dir)
                except _Bad as exc:
                    raise fail(key, sub, str(exc)) from None
            sections[key] = cls(**values)
        elif key == "athletes":
            top[key] = _athletes(value, base_dir, fail)
        elif key in _TOP:
            try:
                top[key] = _convert(_TOP[key], value, base_dir)
            except _Bad as exc:
                raise fail(None, key, str(exc)) from None
        else:
            hint = f" (it belongs in the [{_MOVED[key]}] table)" if key in _MOVED else ""
            valid = ", ".join([*_TOP, *(f"[{s}]" for s in _SECTIONS), "[[athletes]]"])
            raise fail(None, key, f"unknown key{hint}; valid: {valid}")
    config = CourtConfig(**top, **sections)
    try:
        if check:
            check_consistent(config)
    except CourtsideError as exc:
        raise MalformedFileError(path, None, str(exc)) from None
    return config


def _athletes(value: Any, base_dir: Path, fail: Callable[[str | None, str, str], MalformedFileError]
              ) -> tuple[AthleteConfig, ...]:
    """``[[athletes]]`` entries -> `AthleteConfig`s (each key checked; rules across athletes in `check_consistent`)."""
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise fail(None, "athletes", "expected [[athletes]] tables (one per athlete), got " + _describe(value))
    out = []
    for i, entry in enumerate(value):
        values: dict[str, Any] = {}
        for sub, sub_value in entry.items():
            if sub not in _ATHLETE_KEYS:
                raise fail("athletes", sub, f"unknown key in athlete {i + 1}; [[athletes]] takes "
                           f"{', '.join(_ATHLETE_KEYS)}")
            try:
                values[sub] = _convert(_ATHLETE_KEYS[sub], sub_value, base_dir)
            except _Bad as exc:
                raise fail("athletes", sub, f"athlete {i + 1}: {exc}") from None
        if "name" not in values:
            raise fail(None, "athletes", f"athlete {i + 1} has no name")
        out.append(AthleteConfig(**values))
    return tuple(out)


def with_overrides(config: CourtConfig, overrides: dict[str, Any], flags: dict[str, str] | None = None) -> CourtConfig:
    """Apply command-line values (``{"listen": "0.0.0.0:7766", "camera.source": "clip.mp4", ...}``; None =
    not given) through the same checks as the file; a bad one raises `CourtsideError` naming the flag
    (``flags[dotted key]``, default ``--key``)."""
    top: dict[str, Any] = {}
    per_section: dict[str, dict[str, Any]] = {}
    for dotted, value in overrides.items():
        if value is None:
            continue
        section, _, key = dotted.rpartition(".")
        checks = _SECTIONS[section][1] if section else _TOP
        if key not in checks:
            raise KeyError(f"no config key {dotted!r}")  # a programming error, not user input
        flag = (flags or {}).get(dotted) or "--" + key.replace("_", "-")
        try:
            converted = _convert(checks[key], list(value) if isinstance(value, tuple) else value, None)
        except _Bad as exc:
            raise CourtsideError(f"{flag}: {exc}") from None
        (per_section.setdefault(section, {}) if section else top)[key] = converted
    config = replace(config, **top, **{s: replace(getattr(config, s), **v) for s, v in per_section.items()})
    check_consistent(config)
    return config


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and "localhost": addresses no other machine can reach."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _same_file(a: Path, b: Path | None) -> bool:
    """True when ``a`` and ``b`` name one file (equal paths, or links to one inode)."""
    if b is None:
        return False
    try:
        return a.resolve() == b.resolve() or a.samefile(b)
    except OSError:  # a missing file is reported when the secrets are read, naming it
        return False


def check_consistent(config: CourtConfig) -> None:
    """Rules across keys (checked after flags are applied, so a flag can fix what the file lacks)."""
    auth = config.auth
    if not is_loopback(config.listen[0]) and auth.operator_secret_file is None:
        raise CourtsideError(
            f"listening on {config.listen[0]}:{config.listen[1]} (beyond loopback) needs authentication: set "
            "[auth] operator_secret_file (or --secret-file); see docs/gateway.md \"Two machines\"")
    if auth.viewer_secret_file is not None and auth.operator_secret_file is None:
        raise CourtsideError("auth.viewer_secret_file needs auth.operator_secret_file too")
    if auth.viewer_secret_file is not None and _same_file(auth.viewer_secret_file, auth.operator_secret_file):
        raise CourtsideError(f"auth.viewer_secret_file and auth.operator_secret_file are the same file "
                             f"({auth.viewer_secret_file}): a viewer would be an operator; give each role its own "
                             "secret (`courtside gateway new-secret FILE`)")
    if (auth.tls_cert is None) != (auth.tls_key is None):
        raise CourtsideError("TLS needs both auth.tls_cert and auth.tls_key")
    _check_athletes(config)
    if config.camera.source is not None and config.camera.court is None:
        raise CourtsideError("camera.source is set but camera.court is not: give the court calibration file "
                             "(`courtside camera calibrate ... --out court.json`)")


def _check_athletes(config: CourtConfig) -> None:
    """Two athletes must be told apart: distinct names, disjoint sensors, a side each (one near, one far, where
    the camera first finds them), one placement per sensor; one athlete may leave ``sensors`` out (= all)."""
    athletes = config.athletes
    names = [a.name for a in athletes]
    for name in names:
        if names.count(name) > 1:
            raise CourtsideError(f"athletes: the name {name!r} is used twice")
    seen: dict[SensorRef, str] = {}
    for a in athletes:
        if a.placements and a.sensors and len(a.placements) != len(a.sensors):
            raise CourtsideError(f"athletes: {a.name!r} lists {len(a.sensors)} sensors but {len(a.placements)} "
                                 "placements (one site per sensor, in the same order)")
        for ref in a.sensors:
            if ref in seen:
                raise CourtsideError(f"athletes: sensor {ref} is worn by both {seen[ref]!r} and {a.name!r}")
            seen[ref] = a.name
    if len(athletes) > 1:
        for a in athletes:
            if not a.sensors:
                raise CourtsideError(f"athletes: {a.name!r} lists no sensors (with several athletes each names "
                                     "its own, e.g. sensors = [\"st1:0\", \"st1:1\"])")
        sides = [a.side for a in athletes]
        if None in sides or len(set(sides)) != len(sides):
            raise CourtsideError("athletes: each athlete needs its own side (\"near\" / \"far\"): the camera "
                                 f"tells them apart by where it first finds them; got {sides}")
