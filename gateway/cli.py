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


def available_commands() -> dict[str, EntryPoint]:
    """Subcommand name -> entry point, as declared in pyproject.toml."""
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def _usage(commands: dict[str, EntryPoint]) -> str:
    names = "\n".join(f"  {name}" for name in sorted(commands))
    return f"usage: courtside <command> [options]\n\ncommands:\n{names}\n\n`courtside <command> --help` for details."


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
