"""Names that clients (and the command line) choose and the gateway turns into files: take names, calibration
record names.

Why strict: these names become path components under a directory the gateway owns (``<record_dir>/<take>``,
``<records_dir>/<name>.calibration.json``). A name with a separator, ``..``, a leading dot, a newline or a
control character would escape that directory, hide a file, or break a log line (issue 12). So a name is 1-100
characters of ``A-Z a-z 0-9 _ . -`` starting with a letter, digit or underscore (hence never dot-only, never an
option-like ``-x``), matched against the whole string (``re.match`` with ``$`` accepts a trailing newline).
"""
from __future__ import annotations

import re
from typing import Callable

from engine.errors import CourtsideError

MAX_NAME_CHARS = 100
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,%d}" % (MAX_NAME_CHARS - 1))


class BadNameError(CourtsideError, ValueError):
    """A client- or user-chosen name that must not become a path component."""


def check_name(name: object, what: str = "name") -> str:
    """Return ``name`` if it is a safe single path component, else raise `BadNameError` saying why."""
    if not isinstance(name, str):
        raise BadNameError(f"{what} must be a string, got {type(name).__name__}")
    if _NAME.fullmatch(name):
        return name
    if not name:
        problem = "is empty"
    elif len(name) > MAX_NAME_CHARS:
        problem = f"is {len(name)} characters long (at most {MAX_NAME_CHARS})"
    elif not name.isprintable():
        problem = "contains a control character"
    elif "/" in name or "\\" in name:
        problem = "contains a path separator"
    elif name.startswith("."):
        problem = "starts with a dot"
    else:
        problem = "may only use letters, digits, '_', '.', '-' and must start with a letter, digit or '_'"
    shown = name if len(name) <= 40 else name[:40] + "..."
    raise BadNameError(f"{what} {shown!r} {problem}")


def free_name(name: str, exists: Callable[[str], bool], limit: int = 1000) -> str:
    """``name`` if unused, else ``name-2``, ``name-3`` ... (the first unused): how a restarted daemon asked to
    record the same take again continues into a new take instead of refusing (issue 13)."""
    check_name(name)
    if not exists(name):
        return name
    for k in range(2, limit + 2):
        candidate = f"{name[:MAX_NAME_CHARS - len(str(k)) - 1]}-{k}"
        if not exists(candidate):
            return candidate
    raise BadNameError(f"takes {name!r} .. {name}-{limit + 1} all exist; choose another take name")
