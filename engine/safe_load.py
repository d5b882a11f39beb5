"""The one way user files' JSON and TOML are parsed: depth-safe, every failure a `MalformedFileError`.

Why one place (issue 22): ``[[[[…`` 100 000 deep as a calibration record or a court JSON ended in a
`RecursionError` traceback, because each loader caught only the decode errors it knew about. Both `json` and
`tomllib` recurse per nesting level, and a 5 000-digit integer raises a plain `ValueError`. Every JSON/TOML
document that comes from a user's file (calibration records, court calibrations, clicks, court configs, the JSON
inside a graph or take) goes through these functions, so the whole class fails as one line naming the file.

Documents are also refused when nested deeper than `MAX_DEPTH` (checked without recursion: nothing the project
writes is deeper than a few levels, and a bound keeps any later recursive walk of the document safe) or, for
JSON, when a key or string holds a NUL character (the TOML config's schema refuses those naming the key).
"""
from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path
from typing import Any, Callable

from engine.errors import MalformedFileError

MAX_DEPTH = 64  # deepest nesting accepted; the project's own documents use at most ~5 levels


def _structure_problem(doc: Any, nul_ok: bool) -> str | None:
    """Why ``doc`` is refused: nested deeper than `MAX_DEPTH`, or (unless ``nul_ok``) a NUL character in a key or
    string (no path, name or label may hold one; the OS would cut or refuse it later, far from this file).
    Iterative: safe on any depth."""
    stack: list[tuple[Any, int]] = [(doc, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, str):
            if "\x00" in item and not nul_ok:
                return f"a string holds a NUL character (\\u0000): {item[:40]!r}"
            continue
        children = [*item.keys(), *item.values()] if isinstance(item, dict) else item if isinstance(item, list) else None
        if children is None:
            continue
        if depth > MAX_DEPTH:
            return f"nested more than {MAX_DEPTH} levels deep (not a Courtside document)"
        stack.extend((child, depth + 1) for child in children)
    return None


def _too_deep(path: str | Path) -> MalformedFileError:
    return MalformedFileError(path, None, f"nested more than {MAX_DEPTH} levels deep (not a Courtside document)")


def _check_structure(doc: Any, path: str | Path, nul_ok: bool) -> None:
    problem = _structure_problem(doc, nul_ok)
    if problem:
        raise MalformedFileError(path, None, problem)


def _parse(loads: Callable[[Any], Any], text: str | bytes, path: str | Path, nul_ok: bool = False) -> Any:
    """``loads(text)`` with every way it fails (syntax, depth, huge integers, not UTF-8) as one
    `MalformedFileError` naming ``path``; then the structure check."""
    try:
        doc = loads(text)
    except json.JSONDecodeError as exc:
        raise MalformedFileError(path, exc.lineno, f"not JSON ({exc.msg})") from None
    except tomllib.TOMLDecodeError as exc:
        raise MalformedFileError(path, *_toml_where(str(exc))) from None
    except UnicodeDecodeError:
        raise MalformedFileError(path, None, "not a text file (not UTF-8)") from None
    except RecursionError:
        raise _too_deep(path) from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise MalformedFileError(path, None, f"not usable ({str(exc)[:120]})") from None
    _check_structure(doc, path, nul_ok)
    return doc


def parse_json(text: str | bytes, path: str | Path) -> Any:
    """``text`` as JSON; any problem is a `MalformedFileError` naming ``path`` (the file the text came from, or
    e.g. ``"g.npz: 'header_json'"``)."""
    return _parse(json.loads, text, path)


def read_bytes(path: str | Path) -> bytes:
    """The file's bytes; an unreadable file (missing, a directory, no permission) is a `MalformedFileError`."""
    try:
        return Path(path).read_bytes()
    except OSError as exc:
        raise MalformedFileError(path, None, f"cannot read: {exc.strerror or exc}") from None


def read_json(path: str | Path) -> Any:
    """The JSON document in the file ``path`` (see `parse_json`)."""
    return parse_json(read_bytes(path), path)


def parse_toml(text: str, path: str | Path) -> dict[str, Any]:
    """``text`` as TOML; syntax errors keep their line (``MalformedFileError.line``), depth is bounded. NUL
    characters are left to the caller's schema, which can name the key (`gateway.court_config` does)."""
    return _parse(tomllib.loads, text, path, nul_ok=True)


def _toml_where(message: str) -> tuple[int | None, str]:
    """(line, problem) from a TOMLDecodeError message (Python 3.11 has no ``lineno`` attribute)."""
    where = re.search(r"\(at line (\d+), column (\d+)\)", message)
    if where is None:
        return None, f"not valid TOML: {message.strip()}"
    problem = message.replace(where[0], f"(column {where[2]})").strip()
    return int(where[1]), f"not valid TOML: {problem}"
