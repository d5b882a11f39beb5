"""The `courtside` command: a thin dispatcher over the ``courtside.commands`` entry points.

Why entry points: each subcommand lives in the package that owns it, and only the chosen one is imported.
That keeps the headless gateway free of Qt/OpenGL imports (`gui/` is never imported from here), and a
missing optional extra surfaces as a clear message instead of an ImportError at start-up.
"""
from __future__ import annotations

import sys
from importlib.metadata import EntryPoint, entry_points

from engine.errors import report_errors

ENTRY_POINT_GROUP = "courtside.commands"
# One line per command for `courtside --help`. Kept here, not read from each command's parser, because loading a
# parser imports its package (Qt and OpenGL for the console): the list must print on a headless gateway box.
# tests/test_cli_help.py checks it names exactly the declared entry points.
SUMMARIES = {
    "demo": "everything on one machine: emulated athletes, camera, gateway and the console",
    "console": "the operator console for a running gateway, or a recorded take (--playback)",
    "gateway": "read the base stations and the camera, record takes, serve consoles (--config court.toml)",
    "emulate": "emulated base stations on pseudo-terminals, for a gateway without hardware",
    "camera": "overhead camera: render a synthetic court video, calibrate a court, track the player",
    "calibrate": "sensor-to-segment calibration record from a recorded take (what the live wizard saves)",
    "import-imu": "convert another system's IMU recording (CSV, Xsens, x-IMU3) into a take",
    "synthesize": "full-body poses from a recorded take (motion graph, OLNG or HMM) as BVH or a poses file",
    "build-graph": "build a motion graph from mocap clips (the synthesis database)",
    "graph-info": "what a motion graph covers: size, components, dead ends, speeds",
    "evaluate": "measure the synthesis engines on held-out mocap clips",
    "reconstruct": "full-body motion from worn sensors by the OLNG, HMM or motion graph, or their common table",
    "label": "label the markers of every frame of a C3D capture from its labelled training frames",
    "fit-skeleton": "fit a skeleton (joint centres, bone lengths) to a labelled C3D capture, as BVH",
}


def available_commands() -> dict[str, EntryPoint]:
    """Subcommand name -> entry point, as declared in pyproject.toml."""
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def _usage(commands: dict[str, EntryPoint]) -> str:
    """Every command with its one-line summary, in `SUMMARIES`' order (what a newcomer runs first, first)."""
    names = [name for name in SUMMARIES if name in commands] + sorted(set(commands) - set(SUMMARIES))
    width = max(map(len, names), default=0)
    lines = "\n".join(f"  {name:<{width}}  {SUMMARIES.get(name, '')}".rstrip() for name in names)
    return (f"usage: courtside <command> [options]\n\nLive motion capture from body-worn IMUs.\n\ncommands:\n{lines}"
            f"\n\n`courtside <command> --help` for a command's options.")


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    commands = available_commands()
    if not argv or argv[0] in {"-h", "--help", "help"}:
        print(_usage(commands))
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    if name not in commands:
        print(f"courtside: unknown command {name!r}\n\n{_usage(commands)}", file=sys.stderr)
        return 2
    try:
        command = commands[name].load()
    except ImportError as exc:
        print(
            f"courtside {name}: cannot load ({exc}). "
            "GUI commands need the console extra: pip install 'courtside[console]'",
            file=sys.stderr,
        )
        return 2
    return report_errors(f"courtside {name}", command, rest)


if __name__ == "__main__":
    sys.exit(main())
