"""Reading the project's versioned JSON documents (court calibration, sensor-calibration records).

Why one helper: every saved document carries `schema` + `schema_version`, and a bad file must be rejected with an
error that names the file and the exact problem (unreadable, not JSON, wrong kind, unsupported version). Each
document type passes its own error class so callers can still catch the specific failure. It lives in `engine`
(plain json, no dependencies) so the engine and the gateway read the same documents through it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

from engine.errors import MalformedFileError
from engine.safe_load import read_json

FileErrorFactory = Callable[[Path, str], Exception]


def read_versioned_json(path: str | Path, schema: str, version: int, what: str, error: FileErrorFactory) -> dict[str, Any]:
    """The document at `path` as a dict, after checking it is JSON of `schema` at `version`.

    `what` names the kind of document for the message ("a court calibration"); `error(path, problem)` builds the
    exception raised for any problem."""
    path = Path(path)
    try:
        doc = read_json(path)  # depth-safe: every failure is one MalformedFileError
    except MalformedFileError as exc:
        where = f"line {exc.line}: " if exc.line is not None else ""
        raise error(path, f"{where}{exc.problem}") from None
    if not isinstance(doc, dict) or doc.get("schema") != schema:
        raise error(path, f"not {what} (schema must be {schema!r})")
    if doc.get("schema_version") != version:
        raise error(path, f"unsupported schema_version {doc.get('schema_version')!r}")
    return doc
