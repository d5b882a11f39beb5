"""Progress bars for the long commands (build-graph, evaluate, label, fit-skeleton, synthesize, export, ...).

Why one module: every CLI must behave the same way -- a bar on an operator's terminal, nothing at all in a CI log
or a pipe (stderr is not a TTY) or with ``--quiet`` -- and the loops that take the time sit deep in library code
(clip loading, the Viterbi search, the frame loop of a labeler) that cannot see the command's arguments. The
library loops wrap their iterables in `bar`; the command decides, once, whether bars show (`add_quiet_argument`).

Why tqdm: it is pure Python with no dependencies (the gateway's small board carries it at no cost), has been
maintained since 2013, and draws nothing when told to be disabled, so a disabled bar is just the iterable.
It imports no Qt, so gateway, engine and firmware tools share it.
"""
from __future__ import annotations

import argparse
import sys
from typing import Iterable, Iterator, TypeVar

from tqdm import tqdm

T = TypeVar("T")

_state = {"quiet": False}


def set_quiet(quiet: bool) -> None:
    """Silence (or allow) every bar of this process: the ``--quiet`` flag of the command being run."""
    _state["quiet"] = bool(quiet)


def shown() -> bool:
    """Whether a bar started now would be drawn: only on a terminal, and not after ``--quiet``."""
    stream = sys.stderr
    return not _state["quiet"] and stream is not None and hasattr(stream, "isatty") and stream.isatty()


class _QuietAction(argparse.Action):
    """``--quiet`` sets the module's switch at parse time, so library loops see it without being passed it."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        setattr(namespace, self.dest, True)
        set_quiet(True)


def add_quiet_argument(parser: argparse.ArgumentParser) -> None:
    """Add ``--quiet`` to a command's parser; building the parser re-arms the bars, so a process running several
    commands (the tests do) gets each command's own choice."""
    set_quiet(False)
    parser.add_argument("--quiet", nargs=0, action=_QuietAction, default=False,
                        help="no progress bars (they are also off when stderr is not a terminal)")


def bar(iterable: Iterable[T] | None = None, *, total: int | float | None = None, desc: str = "",
        unit: str = "it") -> Iterator[T] | tqdm:
    """A progress bar over ``iterable`` (or a manual one with ``total``, advanced by ``.update(n)``), on stderr.

    When bars are not shown this is the iterable itself (or a disabled tqdm, whose ``update`` does nothing), so a
    loop in a test or a CI log pays nothing and prints nothing."""
    if not shown():
        return iterable if iterable is not None else tqdm(total=total, disable=True)
    return tqdm(iterable, total=total, desc=desc, unit=unit, file=sys.stderr, leave=False, dynamic_ncols=True,
                mininterval=0.2)
