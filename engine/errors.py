"""The project's error root and its one bad-file error.

Every error the project raises on purpose (bad file, bad argument, bad device field, refused request) derives from
`CourtsideError`, so the `courtside` dispatcher can turn any of them into one line and a non-zero exit the same
way, and a traceback always means a bug. Bad input files raise `MalformedFileError`, which names the file, the
location when known, and the problem. `engine` is pure numpy/scipy, so gateway and firmware code can import this
module without pulling in anything heavy."""
from __future__ import annotations

import argparse
import functools
import sys
from pathlib import Path
from typing import Callable


class CourtsideError(Exception):
    """Root of every deliberate Courtside error: the message is the whole user-facing explanation."""


class MalformedFileError(CourtsideError, ValueError):
    """A data file (BVH, ASF, AMC, C3D, cache...) could not be parsed.

    `line` is the 1-based line number when the problem can be pinned to a line, else None
    (binary formats, or problems that concern the whole file)."""

    def __init__(self, path: str | Path, line: int | None, problem: str) -> None:
        self.path = str(path)
        self.line = line
        self.problem = problem
        where = f"{self.path}, line {line}" if line is not None else self.path
        super().__init__(f"{where}: {problem}")


class UsageError(CourtsideError):
    """A bad command-line argument (argparse's own checks: unknown option, missing value, bad choice)."""


class DefaultsHelpFormatter(argparse.HelpFormatter):
    """argparse's help with each option's default said after its text, unless the text already says it or there is
    no value to say (None, a flag, an empty list): argparse's own `ArgumentDefaultsHelpFormatter` would print
    "(default: None)" and repeat the many defaults the texts name in their own words."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if (not action.option_strings or "default" in text.lower() or isinstance(default, bool)
                or not isinstance(default, (int, float, str, Path)) or default == argparse.SUPPRESS):
            return text
        return f"{text} (default: %(default)s)"


class ArgumentParser(argparse.ArgumentParser):
    """argparse in the project's one error style: a bad argument raises `UsageError`, which the dispatcher (or
    `cli_command`) reports as one line with exit status 2, like any other bad input, instead of argparse's usage
    block and `SystemExit`. ``--help`` says each option's default (`DefaultsHelpFormatter`)."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", DefaultsHelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> None:  # type: ignore[override]
        raise UsageError(f"{message} (see {self.prog} --help)")


def check_output_dir(path: str | Path) -> None:
    """Refuse an output whose directory does not exist, before any work is done (so nothing is half-written)."""
    parent = Path(path).resolve().parent
    if not parent.is_dir():
        raise CourtsideError(f"{path}: output directory {parent} does not exist")


def one_line(exc: BaseException) -> str:
    """The error's message on one line (parser messages may quote multi-line input)."""
    return " ".join(str(exc).split())


def report_errors(prog: str, command: Callable[[list[str]], int | None], argv: list[str]) -> int:
    """Run ``command(argv)``; a `CourtsideError` becomes one line ``prog: message`` on stderr and exit status 2.

    Why one function: every CLI (the `courtside` dispatcher, each subcommand called directly, the ``python -m``
    tools) must report a bad file or argument the same way, and anything else escaping is a bug whose traceback
    should be seen."""
    try:
        return int(command(argv) or 0)
    except CourtsideError as exc:
        print(f"{prog}: {one_line(exc)}", file=sys.stderr)
        return 2


def cli_command(prog: str) -> Callable[[Callable[[list[str]], int | None]], Callable[[list[str]], int]]:
    """Decorator form of `report_errors` for a subcommand's ``main(argv)``."""

    def wrap(command: Callable[[list[str]], int | None]) -> Callable[[list[str]], int]:
        @functools.wraps(command)
        def main(argv: list[str] | None = None) -> int:
            return report_errors(prog, command, list(sys.argv[1:] if argv is None else argv))

        return main

    return wrap
