"""`courtside gateway` (and `gateway export`, `gateway new-secret`): the command line around `Gateway`.

Apart from the `Gateway` class (`gateway.daemon.core`) because it builds a whole court through
`gateway.assembly`, which itself builds the `Gateway`: the class, the assembly and the command line are three
layers, imported in that order."""
from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
import time
from pathlib import Path

from engine.errors import ArgumentParser, CourtsideError, MalformedFileError, cli_command
from engine.progress import add_quiet_argument
from gateway import auth
from gateway.court_config import CourtConfig
from gateway.recorder import export_take

from .core import DEFAULT_LISTEN

_DEFAULTS = CourtConfig()  # what an option not given (and not in --config) is: its help says so

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
    p = ArgumentParser(
        prog="courtside gateway",
        description="The gateway: station readers + one clock + recorder + streaming server.",
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
                   help="emulated sensors replay mocap clips or stay still "
                        f"(default {_DEFAULTS.stations.emulate_motion})")
    g.add_argument("--emulate-clip", action="append", default=None, metavar="CLIP",
                   help="shipped clip name or .bvh/.amc file to replay (repeatable; default every shipped clip)")
    g.add_argument("--emulate-orientation", action=argparse.BooleanOptionalAction, default=None,
                   help="emulated sensors also stream orientation quaternions (realistic filter error: per-sensor "
                        "yaw, drift, tilt noise, misalignment) and angular rate (protocol v2)")
    g = p.add_argument_group("camera")
    g.add_argument("--camera", default=None, metavar="SRC", help="V4L2 index, device path or video file")
    g.add_argument("--court", type=Path, default=None, metavar="JSON",
                   help="court calibration (`courtside camera calibrate ... --out court.json`)")
    g.add_argument("--player-side", default=None, metavar="near|far",
                   help="half the player starts on (default: the largest moving figure anywhere)")
    g.add_argument("--camera-fps", type=float, default=None,
                   help="frame rate asked of a live camera (default: the camera's own; files play at their rate)")
    g.add_argument("--camera-loop", action=argparse.BooleanOptionalAction, default=None,
                   help="play a video file again at its end (default: no)")
    g = p.add_argument_group("calibration")
    g.add_argument("--placements", type=lambda text: [s.strip() for s in text.split(",") if s.strip()], default=None,
                   metavar="SITE,SITE,...", help="worn sensor sites: attaches the calibration wizard")
    g.add_argument("--pose", default=None, metavar="npose|tpose",
                   help=f"calibration pose (default {_DEFAULTS.calibration.pose})")
    g.add_argument("--calibration-dir", type=Path, default=None,
                   help=f"where calibration records are saved (default ./{_DEFAULTS.calibration.records_dir})")
    g = p.add_argument_group("recording and network")
    g.add_argument("--record-dir", type=Path, default=None,
                   help=f"where takes are written (default ./{_DEFAULTS.record_dir})")
    g.add_argument("--record", metavar="TAKE", help="start recording this take at once (TAKE-2... if it exists)")
    g.add_argument("--listen", default=None, help=f"host:port for clients (default {DEFAULT_LISTEN}; beyond "
                   "loopback needs --secret-file)")
    g.add_argument("--secret-file", type=Path, default=None, help="operator secret (every client authenticates)")
    g.add_argument("--viewer-secret-file", type=Path, default=None, help="viewer secret (watch only)")
    g.add_argument("--tls-cert", type=Path, default=None, help="PEM certificate: serve TLS")
    g.add_argument("--tls-key", type=Path, default=None, help="PEM private key for --tls-cert")
    g.add_argument("--max-clients", type=int, default=None, metavar="N",
                   help=f"consoles and other clients connected at once; more are refused (default "
                        f"{_DEFAULTS.max_clients})")
    g.add_argument("--handshake-timeout", type=float, default=None, metavar="S",
                   help=f"seconds a new client has to authenticate before it is dropped (default "
                        f"{_DEFAULTS.handshake_timeout_s:g})")
    g = p.add_argument_group("lab streaming layer")
    g.add_argument("--lsl", action="store_const", const=True, default=None,
                   help="publish one LSL outlet per station (pip install 'courtside[lsl]')")
    g.add_argument("--lsl-scope", default=None, help="machine (default: liblsl kept on 127.0.0.1) or network")
    p.add_argument("--duration", type=float, default=None, help="exit after this many seconds (default: run until "
                   "stopped: Ctrl+C or SIGTERM)")
    p.add_argument("--quiet", action="store_true",
                   help="no status lines and no INFO log lines: warnings and errors only (the 'gateway listening "
                        "on HOST:PORT' line stays, scripts read the port from it)")
    p.add_argument("--log-level", default=None,
                   help=f"DEBUG, INFO, WARNING or ERROR (default {_DEFAULTS.log_level}; WARNING with --quiet)")
    return p


def _export_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="courtside gateway export", description="Export a recording to npz and/or CSV")
    p.add_argument("recording", type=Path, help="take directory or its take.csrec")
    p.add_argument("--npz", type=Path, help="output .npz file")
    p.add_argument("--csv-dir", type=Path, help="output directory for CSV files")
    p.add_argument("--xdf", type=Path, help="output .xdf file (Lab Streaming Layer format, one stream per station)")
    add_quiet_argument(p)
    return p


def load_config(args: argparse.Namespace) -> CourtConfig:
    """The court config file (or the defaults) with the command line's options applied on top."""
    from gateway.court_config import check_consistent, load_court_config, with_overrides

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


@cli_command("courtside gateway export")
def _export_main(argv: list[str]) -> int:
    args = _export_parser().parse_args(argv)
    if not args.npz and not args.csv_dir and not args.xdf:
        raise CourtsideError("give --npz, --csv-dir and/or --xdf")
    if args.npz or args.csv_dir:  # a bad recording raises RecordingError: the dispatcher reports it in one line
        for path in export_take(args.recording, args.npz, args.csv_dir):
            print(f"wrote {path}")
    if args.xdf:
        from gateway.xdf import export_xdf

        print(f"wrote {export_xdf(args.recording, args.xdf)}")
    return 0


@cli_command("courtside gateway new-secret")
def _new_secret_main(argv: list[str]) -> int:
    p = ArgumentParser(prog="courtside gateway new-secret",
                       description="Write a new random secret to FILE (mode 600; never overwrites).")
    p.add_argument("file", type=Path, help="where the secret goes: give it to `--secret-file` (or [auth] in the "
                   "court config) here and on each console machine")
    args = p.parse_args(argv)
    try:
        auth.write_secret_file(args.file)
    except OSError as exc:
        raise CourtsideError(f"{args.file}: {exc.strerror or exc}") from None
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
    level = logging.WARNING if args.quiet and args.log_level is None else config.log_level
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
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
