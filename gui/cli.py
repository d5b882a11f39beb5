"""`courtside console` and `courtside demo` (entry points declared in pyproject.toml).

console: connect to a running gateway (`--connect host:port`) or open a recorded take (`--playback`).
demo:    start everything in one command — emulated base stations replaying held-out real mocap as worn
         accelerometers, a synthetic overhead camera with the real tracker, the gateway (in a child process) —
         and open the console on it. `--duration` exits after that many seconds (CI / Xvfb); `--screenshots DIR` saves PNGs first."""
from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from engine.errors import ArgumentParser, CourtsideError, cli_command

log = logging.getLogger("courtside.console")


def _host_port(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit():
        raise argparse.ArgumentTypeError(f"expected host:port, got {text!r}")
    return host or "127.0.0.1", int(port)


def _console_parser() -> argparse.ArgumentParser:
    from engine.stream.registry import engine_names

    p = ArgumentParser(prog="courtside console", description="Operator console for a Courtside gateway.",
                       epilog="Unattended capture: courtside console --connect HOST:PORT --calibrate "
                                       "--record TAKE --duration 60 --save-poses take.poses.npz (no window needed: "
                                       "QT_QPA_PLATFORM=offscreen).")
    p.add_argument("--connect", type=_host_port, default=("127.0.0.1", 7766), metavar="HOST:PORT",
                   help="gateway to connect to (default 127.0.0.1:7766)")
    p.add_argument("--secret-file", type=Path, default=None, metavar="FILE",
                   help="secret for a gateway that requires authentication (default: $COURTSIDE_SECRET_FILE, "
                        "or the secret itself in $COURTSIDE_SECRET); never give the secret itself here")
    p.add_argument("--tls-ca", type=Path, default=None, metavar="CERT",
                   help="connect with TLS, trusting this certificate (the gateway's cert.pem or its CA)")
    p.add_argument("--playback", type=Path, metavar="TAKE",
                   help="open a recorded take (directory or take.csrec), or an IMU file `courtside import-imu` "
                        "wrote (.npz: its sensors by their placement names, so a `courtside calibrate` record of "
                        "it applies; the poses are the ones `courtside synthesize --lag` gives the file)")
    p.add_argument("--engine", choices=engine_names(), default=None,
                   help="synthesis engine (default: motion-graph with --graph, olng with --kb, else by the number "
                        "of worn sensors: 4 -> olng, 1 -> hmm (an accelerometer-only model trained from the shipped "
                        "clips: the stations stream no gyroscope), otherwise motion-graph; see docs/console.md)")
    p.add_argument("--graph", type=Path, default=None, metavar="G.npz",
                   help="motion graph from `courtside build-graph` (default: built from the shipped clips, cached)")
    p.add_argument("--kb", type=Path, default=None, metavar="KB.npz",
                   help="OLNG knowledge base from `courtside reconstruct --save-kb` (default: built from the shipped clips)")
    p.add_argument("--synth-station", default=None, metavar="ST",
                   help="station whose sensors 0..N-1 are worn as the engine's N sensors (default: the only station "
                        "with >= N sensors, if there is exactly one); a --calibration record's assignment wins")
    p.add_argument("--lag", type=float, default=0.5, help="synthesis fixed lag, seconds (default 0.5)")
    p.add_argument("--calibration", type=Path, default=None, metavar="RECORD",
                   help="sensor-calibration record (.calibration.json from the calibration workflow): the motion "
                        "graph's virtual sensors use its measured sensor-to-segment rotations, and synthesis reads "
                        "each segment from the live sensor the record assigned to it")
    p.add_argument("--duration", type=float, default=None,
                   help="close after this many seconds (with --record: the take's length; the console then closes "
                        "once the gateway confirms the stop)")
    p.add_argument("--screenshots", type=Path, default=None, metavar="DIR", help="save PNGs before closing")
    p.add_argument("--calibrate", action="store_true",
                   help="scripted: run the gateway's calibration wizard through this console at start (assign from "
                        "the sensor map, capture the pose, skip the tap, accept) and save the record on the gateway")
    p.add_argument("--record", default=None, metavar="TAKE",
                   help="scripted: record this take on the gateway (after --calibrate) until --duration ends")
    p.add_argument("--save-poses", type=Path, default=None, metavar="OUT.npz",
                   help="save every synthesized pose since the last engine (re)start — with --record, the take's "
                        "poses — when the console closes (format: docs/console.md); two athletes: the first's to "
                        "OUT.npz, the second's to OUT.<athlete>.npz")
    p.add_argument("--stream-bvh", default=None, metavar="[HOST:]PORT",
                   help="serve the synthesised poses as BVH over TCP (Axis Neuron convention) to animation tools "
                        "(motion-graph engine); two athletes: the second on PORT+1")
    p.add_argument("--stream-vmc", default=None, metavar="[HOST:]PORT",
                   help="send the synthesised poses as VMC over OSC/UDP (port 39539 by convention: Unity EVMC4U, "
                        "Blender VMC4B, VSeeFace) to HOST (default 127.0.0.1) (motion-graph engine); two athletes: "
                        "the second performer on PORT+1")
    return p


def _demo_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="courtside demo",
                       description="Everything on one machine, no hardware: two emulated athletes (base stations "
                                   "replaying held-out CMU mocap clips as worn sensors over pseudo-terminals), a "
                                   "synthetic overhead camera with the real tracker, the gateway (in a child "
                                   "process) and the console synthesizing both athletes live.",
                       epilog="Headless: courtside demo --duration 60 --screenshots out/ (without a display it runs "
                              "offscreen; ./demo.sh starts Xvfb). Consoles on other machines need a gateway with a "
                              "secret: courtside gateway --config court.toml (docs/gateway.md).")
    p.add_argument("--duration", type=float, default=None, help="exit after this many seconds (default: run until closed)")
    p.add_argument("--screenshots", type=Path, default=None, metavar="DIR", help="save PNGs of the views before exiting")
    p.add_argument("--lag", type=float, default=0.5, help="synthesis fixed lag, seconds (default 0.5)")
    p.add_argument("--listen", type=_host_port, default=("127.0.0.1", 0), metavar="HOST:PORT",
                   help="where the demo gateway listens for more consoles (default: a free port on 127.0.0.1)")
    p.add_argument("--record-dir", type=Path, default=Path("recordings"), help="where takes go (default ./recordings)")
    p.add_argument("--no-camera", action="store_true", help="skip the synthetic camera (saves CPU)")
    p.add_argument("--single-process", action="store_true",
                   help="run stations, camera and gateway in the console's process (default: a child process)")
    return p


def _pick_synth_station(stations: list[dict], wanted: str | None, n_sensors: int = 6) -> str | None:
    if wanted:
        return wanted
    big = [s["station"] for s in stations if len(s.get("sensors", [])) >= n_sensors]
    return big[0] if len(big) == 1 else None


def _check_screenshots_have_duration(args: argparse.Namespace) -> None:
    if args.screenshots is not None and args.duration is None:
        raise CourtsideError("--screenshots needs --duration (they are taken just before exiting)")


@cli_command("courtside console")
def console_main(argv: list[str]) -> int:
    args = _console_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    _check_screenshots_have_duration(args)
    if (args.record or args.calibrate) and (args.duration is None or args.playback is not None):
        raise CourtsideError("--record/--calibrate are scripted runs against a gateway: they need --duration and "
                             "no --playback")
    return _console(args)


def _console(args: argparse.Namespace) -> int:
    from engine.mocap import load_sensor_calibration

    from gui.app import application
    from gui.athletes_replay import athlete_stations
    from gui.main_window import ConsoleWindow
    from gui.playback import Playback

    calibration = load_sensor_calibration(args.calibration) if args.calibration is not None else None
    if calibration is not None and calibration.failed:
        log.warning("calibration %s: sensors on %s did not pass the wizard's checks (used anyway)",
                    args.calibration, ", ".join(calibration.failed))
    application()
    client = playback = make_client = None
    held_out: list[str] = []
    truth_for_take = None
    if args.playback is not None:
        try:
            playback = Playback(args.playback)
        except (OSError, ValueError) as exc:
            raise CourtsideError(f"cannot play back {args.playback}: {exc}") from None
        stations = _stations_in_take(playback)
        # a demo take names the clips it replayed: keep them out of the graph, as the live demo does
        held_out = next((e["truth_clips"] for e in playback.events if "truth_clips" in e), [])
        if held_out:
            from gui.demo import truth_from_events  # only demo takes carry ground truth

            truth_for_take = truth_from_events
    else:
        make_client = _client_factory(args)
        try:
            client = make_client(*args.connect).connect()
        except OSError as exc:
            raise CourtsideError(f"cannot connect to gateway {args.connect[0]}:{args.connect[1]} ({exc})") from None
        if (args.record or args.calibrate) and getattr(client, "role", "operator") == "viewer":
            client.close()  # refuse before anything runs: the gateway would refuse every step (and the wizard's
            # refusals would only surface when it timed out, 90 s later)
            raise CourtsideError(f"--calibrate/--record need the operator role, but gateway "
                                 f"{args.connect[0]}:{args.connect[1]} accepted this console's secret as a viewer "
                                 "(watch only): give the operator secret file")
        stations = _stations_with_sensors(client)
    athletes = {} if args.synth_station else playback.athlete_stations() if playback is not None else (
        athlete_stations((getattr(client, "server_hello", {}) or {}).get("athletes"), stations))
    try:
        refresh = client.list_stations if client is not None else None
        more: dict = {}
        athlete = None
        if len(athletes) > 1:  # one synthesis per athlete, each from its own station's sensors
            runs = {name: _synthesis(_athlete_args(args, station, k), stations, calibration, held_out, refresh)
                    for k, (name, station) in enumerate(athletes.items())}
            athlete, (synth, worn, skeleton_parents) = next(iter(runs.items()))
            more = {name: run[0] for name, run in list(runs.items())[1:] if run[0] is not None}
            worn = {key: place for run in runs.values() for key, place in run[1].items()}
        else:
            synth, worn, skeleton_parents = _synthesis(args, stations, calibration, held_out, refresh, playback)
            if playback is not None and synth is not None:
                playback = playback.for_frame_rate(synth.engine.rate_hz)
        window = ConsoleWindow(client, synthesis=synth, truth_parents=skeleton_parents, sensor_segments=worn,
                               sensor_joints=sensor_joints_or_none(worn), truth_for_take=truth_for_take,
                               keep_poses=args.save_poses is not None, make_client=make_client,
                               athlete=athlete, more_athletes=more)
    except BaseException:
        if client is not None:
            client.close()
        raise
    window.resize(1500, 950)
    if playback is not None:
        window.load_playback(playback)
    script = None
    if args.calibrate or args.record:
        from gui.scripted import ScriptedRun

        script = ScriptedRun(window, calibrate=args.calibrate, take=args.record, duration_s=args.duration)
        script.start()
    try:  # a scripted run closes the window itself, when its steps are done
        code = _run_window(window, None if script is not None else args.duration, args.screenshots)
    finally:
        if client is not None:
            client.close()
    if args.save_poses is not None:
        path = window.save_poses(args.save_poses)
        log.info("poses saved to %s", path)
    if script is not None and script.failure:
        print(f"courtside console: {script.failure}", file=sys.stderr)
        return 1
    return code


def _athlete_args(args: argparse.Namespace, station: str, k: int) -> argparse.Namespace:
    """The console's options for athlete ``k``'s synthesis: its station, and its own BVH / VMC port (the
    given port + k: two BVH servers, two VMC performers)."""
    def shifted(target: str | None) -> str | None:
        if target is None or k == 0:
            return target
        host, sep, port = target.rpartition(":")
        return f"{host}{sep}{int(port) + k}"

    return argparse.Namespace(**{**vars(args), "synth_station": station, "stream_bvh": shifted(args.stream_bvh),
                                 "stream_vmc": shifted(args.stream_vmc)})


def _client_factory(args: argparse.Namespace):
    """``(host, port) -> GatewayClient`` with the secret (--secret-file or the environment) and TLS options, for
    the first connection and every reconnect."""
    import functools

    from gateway.auth import client_secret, client_tls_context
    from gateway.client import GatewayClient

    tls = client_tls_context(args.tls_ca) if args.tls_ca is not None else None
    return functools.partial(GatewayClient, secret=client_secret(args.secret_file), tls=tls)


def _synthesis(args: argparse.Namespace, stations: list[dict], calibration, held_out: list[str], refresh=None,
               playback=None):
    """(SynthesisSetup or None, worn sensor -> placement, skeleton parents or None). ``refresh`` re-reads the
    station list (live gateway); a ``playback`` of an imported IMU file names its sensors
    (`gui.engine_link.worn_sensors`)."""
    from engine.stream.databases import engine_spec
    from gui.engine_link import synthesis_setup, worn_sensors

    n_worn = len(calibration.sensor_ids) if calibration is not None and calibration.sensor_ids else (
        _station_size(stations, args.synth_station))
    spec, notes = engine_spec(args.engine, graph_path=args.graph, kb_path=args.kb, n_worn=n_worn or 6,
                              exclude=held_out, calibration=calibration)
    for note in notes:
        log.info("synthesis: %s", note)
    log.info("synthesis: %s", spec.label)
    named = (playback.placements, playback.source_labels) if playback is not None else (None, None)
    try:
        keys, notes = worn_sensors(list(spec.sensor_names),
                                   _pick_synth_station(stations, args.synth_station, len(spec.sensor_names)),
                                   calibration, *named)
    except ValueError as exc:
        raise CourtsideError(str(exc)) from exc
    if keys is None:
        if args.graph or args.kb or args.engine:  # asked for by name: refuse rather than run without it
            candidates = ", ".join(f"{s['station']} ({len(s.get('sensors') or [])} sensors)" for s in stations
                                   if len(s.get("sensors") or []) >= len(spec.sensor_names)) or "none"
            raise CourtsideError(f"{spec.label} needs {len(spec.sensor_names)} worn sensors "
                                 f"({', '.join(spec.sensor_names)}) but nothing says which live sensors those are; "
                                 f"stations that could carry them: {candidates}. Pass --synth-station ST (its "
                                 "sensors 0.. in that order) or --calibration RECORD")
    for note in notes:
        log.warning("synthesis: %s", note)
    if keys is None:
        log.warning("synthesis off: pass --synth-station (or a calibration record) to say which sensors are worn")
        return None, {}, spec.parents
    _check_when_streaming(spec, keys, stations, calibration, refresh)
    if args.stream_bvh or args.stream_vmc:
        from engine.livestream.console import streaming_engine

        spec = streaming_engine(spec, bvh=args.stream_bvh, vmc=args.stream_vmc)
    synth = synthesis_setup(spec, keys, args.lag)
    return synth, dict(zip(synth.sensors, spec.sensor_names)), spec.parents


def _stations_with_sensors(client, wait_s: float = 5.0) -> list[dict]:
    """The gateway's station list once every listed station has reported its sensors, or after ``wait_s`` (a
    gateway that has just started lists stations before their first samples; the engine default depends on how
    many sensors are worn, and which station carries them is decided from all of them: taking the list when the
    first one reported picked a station that was alone only because the other had not reported yet)."""
    import time

    deadline = time.monotonic() + wait_s
    while True:
        stations = client.list_stations()
        if (stations and all(s.get("sensors") for s in stations)) or time.monotonic() > deadline:
            return stations
        time.sleep(0.2)


def _check_when_streaming(spec, keys, stations, calibration, refresh, wait_s: float = 5.0) -> None:
    """`check_worn_sensors`, giving sensors that have not streamed yet (a gateway just started) ``wait_s``."""
    import time

    from engine.stream.engines import SensorsMissingError
    from gui.engine_link import check_worn_sensors

    deadline = time.monotonic() + wait_s
    while True:
        try:
            return check_worn_sensors(spec, keys, stations, calibration)
        except SensorsMissingError:
            if refresh is None or time.monotonic() > deadline:
                raise
        time.sleep(0.25)
        stations = refresh()


def _station_size(stations: list[dict], wanted: str | None) -> int:
    """Sensors on the synthesis station (--synth-station, else the largest)."""
    sizes = {str(s["station"]): len(s.get("sensors", [])) for s in stations}
    if wanted:
        return sizes.get(wanted, 0)
    return max(sizes.values(), default=0)


def sensor_joints_or_none(worn: dict) -> dict | None:
    """Live sensor -> skeleton joint for the 3-D health colours (standard placements on the shipped skeleton)."""
    if not worn:
        return None
    from engine.mocap import load_clip, sample_clips

    from gui.engine_link import sensor_joints

    return sensor_joints(load_clip(sample_clips()["16_01"]).skeleton, worn)


def _stations_in_take(playback) -> list[dict]:
    """Station list shaped like the gateway's (``station``, ``sensors``) from a take's sample streams."""
    sensors: dict[str, list[dict]] = {}
    for station, sensor in sorted(playback.samples):
        sensors.setdefault(station, []).append({"sensor": sensor})
    return [{"station": st, "sensors": s} for st, s in sensors.items()]


def _run_window(window, duration_s: float | None, screenshots: Path | None) -> int:
    from PySide6 import QtCore

    from gui.app import run
    from gui.screens import capture_console

    if screenshots is not None and duration_s is not None:
        def capture_then_close() -> None:
            log.info("screenshots: %s", [str(p) for p in capture_console(window, screenshots)])
            window.close()

        # one callback, in order: capturing runs nested event loops, and a separate close timer firing inside
        # one of them (a loaded machine: the grabs take longer than the 1.5 s left) closed the window there,
        # where the quit on the last window was lost, and the console never exited
        QtCore.QTimer.singleShot(int(max(0.0, duration_s - 1.5) * 1000), capture_then_close)
        duration_s = None
    code = run(window, duration_s)
    window.shutdown()
    return code


@cli_command("courtside demo")
def demo_main(argv: list[str]) -> int:
    args = _demo_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    _check_screenshots_have_duration(args)
    from gateway.court_config import check_consistent, is_loopback
    from gui.app import application
    from gui.demo.hardware import demo_court_config
    from gui.demo.session import demo_session

    # the demo's court goes through the config loader's rules before anything starts, so a refusal is one line
    # here, not a failure in the hardware process; the demo gateway has no secret, so it stays on loopback
    if not is_loopback(args.listen[0]):
        raise CourtsideError(f"--listen {args.listen[0]}:{args.listen[1]}: the demo gateway has no authentication, "
                             "so it listens on loopback only (127.0.0.0/8); for consoles on other machines run "
                             "`courtside gateway --config court.toml` with an [auth] secret (docs/gateway.md "
                             "\"Two machines\")")
    check_consistent(demo_court_config(args.listen, args.record_dir))
    application()
    with demo_session(lag_s=args.lag, listen=args.listen, record_dir=args.record_dir, camera=not args.no_camera,
                      duration_s=args.duration, separate_process=not args.single_process) as session:
        return _run_window(session.window, args.duration, args.screenshots)
