"""Type checks for every field of every message a client sends, made before any field is used.

Why here and up front (issue 22): the server used fields as it met them, so a non-ASCII ``proof`` made
`hmac.compare_digest` raise TypeError (a traceback and a dropped connection without a reply) and a calibration
``action`` that was a list raised "unhashable" in the role check. Each function below returns None when the
message is well formed, else one line saying which field is wrong; the server answers that line as an
``ok: false`` reply and keeps serving. The schema (docs/gateway.md "Wire format"):

* every message: ``id`` absent, null, an integer or a string of at most `MAX_ID_CHARS` characters;
* ``auth``: ``nonce`` and ``proof`` are 64 lowercase hex characters;
* ``subscribe``: ``topics`` is a list of known topic names;
* ``request``: ``action`` a string, ``args`` absent, null or an object whose keys for that action have the
  types in `ACTION_ARGS` (keys an action does not use are never read).
"""
from __future__ import annotations

import re
from typing import Any

from gateway import wire

MAX_ID_CHARS = 64
_HEX64 = re.compile(r"[0-9a-f]{64}")
_SCALARS = (str, int, float, bool, type(None))

# action -> {argument: expected type}; station command arguments are scalars (the wire carries one i32)
ACTION_ARGS: dict[str, dict[str, type | tuple[type, ...]]] = {
    "start_recording": {"take": str},
    "station_command": {"station": str, "command": str, "args": dict},
    "calibration": {"action": str, "args": dict},
}
_TYPE_NAMES = {str: "a string", dict: "an object", int: "an integer"}


def _kind(value: Any) -> str:
    return {str: "a string", bool: "a boolean", int: "an integer", float: "a number", list: "a list",
            dict: "an object", type(None): "null"}.get(type(value), type(value).__name__)


def id_problem(header: dict[str, Any]) -> str | None:
    """``id`` is echoed in the reply: only a small scalar is accepted."""
    value = header.get("id")
    if value is None or (isinstance(value, int) and not isinstance(value, bool)):
        return None
    if isinstance(value, str) and len(value) <= MAX_ID_CHARS:
        return None
    return f"'id' must be an integer or a string of at most {MAX_ID_CHARS} characters, got {_kind(value)}"


def auth_problem(header: dict[str, Any]) -> str | None:
    for key in ("nonce", "proof"):
        value = header.get(key)
        if not isinstance(value, str) or not _HEX64.fullmatch(value):
            return f"authentication failed: '{key}' must be 64 lowercase hex characters, got {_kind(value)}"
    return None


def topics_problem(header: dict[str, Any]) -> str | None:
    topics = header.get("topics")
    if not isinstance(topics, list) or not all(isinstance(t, str) for t in topics):
        return f"'topics' must be a list of strings, got {_kind(topics)}; valid: {list(wire.TOPICS)}"
    unknown = sorted(set(topics) - set(wire.TOPICS))
    if unknown:
        return f"unknown topics {[t[:40] for t in unknown[:5]]}; valid: {list(wire.TOPICS)}"
    return None


def request_problem(header: dict[str, Any]) -> str | None:
    action, args = header.get("action"), header.get("args")
    if not isinstance(action, str) or not (args is None or isinstance(args, dict)):
        return f"request needs a string 'action' and an object 'args', got {_kind(action)} and {_kind(args)}"
    for key, expected in ACTION_ARGS.get(action, {}).items():
        value = args.get(key) if args else None
        if value is not None and not isinstance(value, expected):
            return f"{action}: '{key}' must be {_TYPE_NAMES.get(expected, expected)}, got {_kind(value)}"  # type: ignore[arg-type]
    if action == "station_command" and args and isinstance(args.get("args"), dict):
        bad = [k for k, v in args["args"].items() if not isinstance(v, _SCALARS)]
        if bad:
            return f"station_command: argument {bad[0][:40]!r} must be a number, string, boolean or null"
    return None
