"""`courtside emulate`: run emulated base stations on pseudo-terminals in real time.

Prints one line per station, `station <id> <slave path>[ <stable symlink>]`, then a blank line, so that
`courtside gateway --port /dev/pts/N` (or a script) can open them. Ctrl-C / SIGTERM stops cleanly.
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path

from engine.errors import ArgumentParser, CourtsideError, cli_command

from .link import EmulatorLink
from .motion import MocapSource, MotionSource, TraceSource
from .options import STATION_OPTIONS, apply_options, parse_flag
from .pty_transport import PtyTransport
from .station import BaseStation, StationConfig


def _parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="courtside emulate", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--stations", type=int, default=1, help="number of stations (ids 1..N, seed + id - 1)")
    for name, (field, parse, help_text) in STATION_OPTIONS.items():
        if parse is parse_flag:
            p.add_argument(f"--{name}", action="store_true", help=help_text)
        else:
            default = getattr(StationConfig(), field)
            p.add_argument(f"--{name}", default=None, metavar="X", help=f"{help_text} (default {default})")
    motion = p.add_mutually_exclusive_group()
    motion.add_argument("--trace", type=Path, help="(frames, sensors, 3) acceleration trace in g, numpy .npy")
    motion.add_argument("--mocap", help="mocap clip (.bvh, or .amc beside its .asf) or a clip name shipped in "
                                        "engine/data (e.g. 16_01); drives the engine's virtual accelerometers")
    p.add_argument("--trace-fps", type=float, default=100.0, help="frame rate of --trace, Hz")
    p.add_argument("--speed", type=float, default=1.0, help="emulated seconds per wall second (1 = real time)")
    p.add_argument("--duration", type=float, default=None, help="stop after this many wall seconds")
    p.add_argument("--link-dir", type=Path, help="also create stable symlinks <dir>/station-<id>")
    p.add_argument("--unplug-every", type=float, default=None, metavar="S",
                   help="pull each station's cable every S wall seconds (reconnect testing)")
    p.add_argument("--unplug-for", type=float, default=1.0, metavar="S", help="how long it stays unplugged")
    return p


def _motion(args: argparse.Namespace) -> MotionSource | None:
    if args.trace is not None:
        if args.orientation:
            raise ValueError(f"{args.trace}: an acceleration trace has no orientation; use --mocap or no motion "
                             "source with --orientation")
        return TraceSource.from_npy(args.trace, args.trace_fps)
    if args.mocap is not None:
        clip: str | Path = args.mocap
        if not Path(clip).exists():
            from engine.mocap import sample_clips   # lazy: only mocap-driven runs need the engine

            clips = sample_clips()
            if clip not in clips:
                raise ValueError(f"{clip}: no such file, and not a shipped clip ({', '.join(sorted(clips))})")
            clip = clips[clip]
        return MocapSource.from_clip(clip, orientation_seed=int(args.seed or 0) if args.orientation else None)
    return None


def _build(args: argparse.Namespace) -> list[tuple[int, EmulatorLink, PtyTransport]]:
    flags = [name for name, (_, parse, _) in STATION_OPTIONS.items() if parse is parse_flag]
    options = {name: getattr(args, name.replace("-", "_")) for name in STATION_OPTIONS if name not in flags}
    base = apply_options(StationConfig(), {k: v for k, v in options.items() if v is not None})
    base = replace(base, **{STATION_OPTIONS[name][0]: True for name in flags if getattr(args, name)})
    motion = _motion(args)
    if args.link_dir is not None:
        args.link_dir.mkdir(parents=True, exist_ok=True)
    stations = []
    for i in range(args.stations):
        sid = base.station_id + i
        config = replace(base, station_id=sid, serial=base.serial + i, seed=base.seed + i)
        link = EmulatorLink(BaseStation(config, motion), realtime=True, speed=args.speed)
        symlink = args.link_dir / f"station-{sid}" if args.link_dir is not None else None
        stations.append((sid, link, PtyTransport(link, symlink=symlink)))
    return stations


@cli_command("courtside emulate")
def main(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    if args.stations < 1 or args.speed <= 0:
        raise CourtsideError("--stations must be >= 1 and --speed > 0")
    try:
        stations = _build(args)
    except (ValueError, OSError) as exc:  # a bad motion file or option value, a link directory not writable
        raise CourtsideError(str(exc)) from None
    stop = threading.Event()
    # Ctrl-C and SIGTERM stop it cleanly, set explicitly as the gateway does: a process started from a script's
    # background job inherits SIGINT ignored, and Python then raises no KeyboardInterrupt (a CI run started so
    # left the emulator running after its test had sent SIGINT)
    previous = {sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        for sid, _, transport in stations:
            link_note = f" {transport.symlink}" if transport.symlink else ""
            print(f"station {sid} {transport.slave_path}{link_note}", flush=True)
        print(flush=True)
        _serve(stations, args, stop)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        for _, _, transport in stations:
            transport.close()
    print("courtside emulate: stopped", file=sys.stderr)
    return 0


def _serve(stations: list[tuple[int, EmulatorLink, PtyTransport]], args: argparse.Namespace,
           stop: threading.Event) -> None:
    start = time.monotonic()
    next_unplug = start + args.unplug_every if args.unplug_every else None
    while not stop.is_set():
        now = time.monotonic()
        if args.duration is not None and now - start >= args.duration:
            return
        if next_unplug is not None and now >= next_unplug:
            for _, _, transport in stations:
                transport.unplug()
            stop.wait(args.unplug_for)
            for sid, _, transport in stations:
                transport.replug()
                print(f"station {sid} {transport.slave_path} replugged", flush=True)
            next_unplug = time.monotonic() + args.unplug_every
        stop.wait(0.05)


if __name__ == "__main__":
    sys.exit(main())
