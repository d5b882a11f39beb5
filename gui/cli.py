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

log = logging.getLogger("courtside.console")


def _host_port(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit():
        raise argparse.ArgumentTypeError(f"expected host:port, got {text!r}")
    return host or "127.0.0.1", int(port)


def _console_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="courtside console", description="Operator console for a Courtside gateway.")
    p.add_argument("--connect", type=_host_port, default=("127.0.0.1", 7766), metavar="HOST:PORT",
                   help="gateway to connect to (default 127.0.0.1:7766)")
    p.add_argument("--secret-file", type=Path, default=None, metavar="FILE",
                   help="secret for a gateway that requires authentication (default: $COURTSIDE_SECRET_FILE, "
                        "or the secret itself in $COURTSIDE_SECRET); never give the secret itself here")
    p.add_argument("--tls-ca", type=Path, default=None, metavar="CERT",
                   help="connect with TLS, trusting this certificate (the gateway's cert.pem or its CA)")
    p.add_argument("--playback", type=Path, metavar="TAKE", help="open a recorded take (directory or take.csrec)")
    p.add_argument("--synth-station", default=None, metavar="ST",
                   help="station whose sensors 0-5 are worn as the graph's sensors (default: the only station "
                        "with >= 6 sensors, if there is exactly one); a --calibration record's assignment wins")
    p.add_argument("--lag", type=float, default=0.5, help="synthesis fixed lag, seconds (default 0.5)")
    p.add_argument("--calibration", type=Path, default=None, metavar="RECORD",
                   help="sensor-calibration record (.calibration.json from the calibration workflow): the motion "
                        "graph's virtual sensors use its measured sensor-to-segment rotations, and synthesis reads "
                        "each segment from the live sensor the record assigned to it")
    p.add_argument("--duration", type=float, default=None, help="close after this many seconds")
    p.add_argument("--screenshots", type=Path, default=None, metavar="DIR", help="save PNGs before closing")
    p.add_argument("--stream-bvh", default=None, metavar="[HOST:]PORT",
                   help="serve the synthesised poses as BVH over TCP (Axis Neuron convention) to animation tools")
    return p


def _demo_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="courtside demo", description=__doc__.split("\n")[0])
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


def _pick_synth_station(stations: list[dict], wanted: str | None) -> str | None:
    if wanted:
        return wanted
    big = [s["station"] for s in stations if len(s.get("sensors", [])) >= 6]
    return big[0] if len(big) == 1 else None


def _screenshots_need_duration(command: str, args: argparse.Namespace) -> bool:
    if args.screenshots is not None and args.duration is None:
        print(f"courtside {command}: --screenshots needs --duration (they are taken just before exiting)",
              file=sys.stderr)
        return True
    return False


def console_main(argv: list[str]) -> int:
    args = _console_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if _screenshots_need_duration("console", args):
        return 2
    from gateway.client import GatewayClient

    from gui.app import application
    from engine.mocap import SEED000_SENSORS

    from gui.engine_link import load_or_build_graph, sensor_joints, synthesis_setup, worn_sensors
    from gui.main_window import ConsoleWindow
    from gui.playback import Playback

    from engine.mocap import MalformedFileError, load_sensor_calibration

    calibration = None
    if args.calibration is not None:
        try:
            calibration = load_sensor_calibration(args.calibration)
        except MalformedFileError as exc:
            print(f"courtside console: {exc}", file=sys.stderr)
            return 2
        if calibration.failed:
            log.warning("calibration %s: sensors on %s did not pass the wizard's checks (used anyway)",
                        args.calibration, ", ".join(calibration.failed))
    application()
    client = playback = None
    held_out: list[str] = []
    if args.playback is not None:
        try:
            playback = Playback(args.playback)
        except (OSError, ValueError) as exc:
            print(f"courtside console: cannot play back {args.playback}: {exc}", file=sys.stderr)
            return 2
        stations = _stations_in_take(playback)
        # a demo take names the clips it replayed: keep them out of the graph, as the live demo does
        held_out = next((e["truth_clips"] for e in playback.events if "truth_clips" in e), [])
    else:
        from gateway.auth import client_secret, client_tls_context

        tls = client_tls_context(args.tls_ca) if args.tls_ca is not None else None
        try:
            client = GatewayClient(*args.connect, secret=client_secret(args.secret_file), tls=tls).connect()
        except OSError as exc:
            print(f"courtside console: cannot connect to gateway {args.connect[0]}:{args.connect[1]} ({exc})",
                  file=sys.stderr)
            return 2
        stations = client.list_stations()
    try:
        graph, skeleton, cache = load_or_build_graph(exclude=held_out, calibration=calibration)
    except ValueError as exc:  # a record made for another skeleton's joint frames
        print(f"courtside console: {exc}", file=sys.stderr)
        if client is not None:
            client.close()
        return 2
    log.info("motion graph %s (%d nodes)", cache, graph.n_nodes)
    synth = None
    segments = list(graph.config.sensor_names or SEED000_SENSORS)
    try:
        keys, notes = worn_sensors(segments, _pick_synth_station(stations, args.synth_station), calibration)
    except ValueError as exc:
        print(f"courtside console: {exc}", file=sys.stderr)
        if client is not None:
            client.close()
        return 2
    for note in notes:
        log.warning("synthesis: %s", note)
    worn: dict = {}
    if keys is not None:
        synth = synthesis_setup(graph, skeleton, keys, args.lag)
        if args.stream_bvh:
            from engine.livestream.console import streaming_setup

            synth = streaming_setup(synth, graph, skeleton, args.stream_bvh)
        worn = dict(zip(synth.sensors, segments))
    else:
        log.warning("synthesis off: pass --synth-station (or a calibration record) to say which sensors are worn")
    window = ConsoleWindow(client, synthesis=synth, truth_parents=skeleton.parents, sensor_segments=worn,
                           sensor_joints=sensor_joints(skeleton, worn) if worn else None)
    window.resize(1500, 950)
    if playback is not None:
        window.load_playback(playback)
    try:
        return _run_window(window, args.duration, args.screenshots)
    finally:
        if client is not None:
            client.close()


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
        QtCore.QTimer.singleShot(int(max(0.0, duration_s - 1.5) * 1000),
                                 lambda: log.info("screenshots: %s", [str(p) for p in capture_console(window, screenshots)]))
    code = run(window, duration_s)
    window.shutdown()
    return code


def demo_main(argv: list[str]) -> int:
    args = _demo_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if _screenshots_need_duration("demo", args):
        return 2
    from gui.app import application
    from gui.demo.session import demo_session

    application()
    with demo_session(lag_s=args.lag, listen=args.listen, record_dir=args.record_dir, camera=not args.no_camera,
                      duration_s=args.duration, separate_process=not args.single_process) as session:
        return _run_window(session.window, args.duration, args.screenshots)
