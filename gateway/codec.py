"""One binary envelope for everything the gateway sends or stores: a JSON header plus named numpy arrays.

Why one codec: the TCP wire format (`gateway.wire`) and the crash-safe recording chunks (`gateway.recorder`)
carry the same messages, so a sample batch is encoded once and the same bytes can be sent or written.

Layout of one encoded body (all integers big-endian)::

    u32 header_len | header_len bytes of UTF-8 JSON | payload bytes

The JSON header is an object with at least ``"kind"``. If arrays are attached, ``header["arrays"]`` lists
``{"name", "dtype", "shape"}`` in payload order; the payload is their raw C-order bytes concatenated. Dtypes are
numpy dtype strings with explicit byte order (``"<f4"``), so the format is portable across machines.
"""
from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from engine.errors import CourtsideError

_U32 = struct.Struct(">I")
MAX_HEADER_BYTES = 1 << 20


class CodecError(CourtsideError, ValueError):
    """A body that cannot be decoded (bad length, bad JSON, array spec that does not match the payload)."""


@dataclass
class Message:
    """A decoded message: ``kind`` + JSON-able header fields + named arrays (read-only views are fine)."""

    kind: str
    header: dict[str, Any] = field(default_factory=dict)
    arrays: dict[str, np.ndarray] = field(default_factory=dict)

    def __getitem__(self, key: str) -> Any:
        """Header field or array by name, so callers write ``msg["acc_g"]`` or ``msg["station"]``."""
        if key in self.arrays:
            return self.arrays[key]
        return self.header[key]

    def get(self, key: str, default: Any = None) -> Any:
        try:
            return self[key]
        except KeyError:
            return default


def _portable(array: np.ndarray) -> np.ndarray:
    """C-contiguous array with an explicit byte order ('|' for 1-byte types), so the dtype string round-trips."""
    array = np.ascontiguousarray(array)
    if array.dtype.byteorder == "=":
        array = array.astype(array.dtype.newbyteorder("<" if np.little_endian else ">"), copy=False)
    return array


def _json_default(value: Any) -> Any:
    """numpy scalars and small arrays in headers become plain JSON (producers need not convert them)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"header value of type {type(value).__name__} is not JSON-serialisable")


def encode(kind: str, header: dict[str, Any] | None = None, arrays: dict[str, np.ndarray] | None = None) -> bytes:
    """Encode one message body (without any outer framing)."""
    head: dict[str, Any] = {"kind": kind, **(header or {})}
    payload_parts: list[bytes] = []
    if arrays:
        specs = []
        for name, value in arrays.items():
            array = _portable(np.asarray(value))
            if array.dtype.hasobject:
                raise CodecError(f"array {name!r} has object dtype; only plain numeric arrays can be sent")
            specs.append({"name": name, "dtype": array.dtype.str, "shape": list(array.shape)})
            payload_parts.append(array.tobytes())
        head["arrays"] = specs
    header_bytes = json.dumps(head, separators=(",", ":"), allow_nan=True, default=_json_default).encode("utf-8")
    return b"".join([_U32.pack(len(header_bytes)), header_bytes, *payload_parts])


def decode(body: bytes | memoryview) -> Message:
    """Decode one body produced by `encode`. Arrays are read-only views into ``body`` (no copy)."""
    view = memoryview(body)
    if len(view) < 4:
        raise CodecError(f"body of {len(view)} bytes is shorter than the 4-byte header length")
    (header_len,) = _U32.unpack_from(view, 0)
    if header_len > MAX_HEADER_BYTES or 4 + header_len > len(view):
        raise CodecError(f"header length {header_len} does not fit in a body of {len(view)} bytes")
    try:
        head = json.loads(bytes(view[4 : 4 + header_len]).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CodecError(f"header is not UTF-8 JSON: {exc}") from exc
    except RecursionError:  # [[[[...]]]] 200 000 deep: json's recursion guard, not a reason to die
        raise CodecError("header JSON is nested too deeply") from None
    if not isinstance(head, dict) or not isinstance(head.get("kind"), str):
        raise CodecError("header must be a JSON object with a string 'kind'")
    arrays: dict[str, np.ndarray] = {}
    offset = 4 + header_len
    for spec in head.pop("arrays", []):
        try:
            dtype = np.dtype(spec["dtype"])
            shape = tuple(int(n) for n in spec["shape"])
            name = str(spec["name"])
        except (KeyError, TypeError, ValueError) as exc:
            raise CodecError(f"bad array spec {spec!r}: {exc}") from exc
        if dtype.hasobject:
            raise CodecError(f"array {name!r} declares an object dtype")
        if any(n < 0 for n in shape) or len(shape) > 32:
            raise CodecError(f"array {name!r} has an invalid shape {list(shape)[:8]}")
        nbytes = dtype.itemsize * math.prod(shape)  # Python ints: [2**32, 2**32] must not wrap to 0
        if offset + nbytes > len(view):
            raise CodecError(f"array {name!r} needs {nbytes} bytes but only {len(view) - offset} remain")
        arrays[name] = np.frombuffer(view[offset : offset + nbytes], dtype=dtype).reshape(shape)
        offset += nbytes
    if offset != len(view):
        raise CodecError(f"{len(view) - offset} trailing bytes after the declared arrays")
    kind = head.pop("kind")
    return Message(kind=kind, header=head, arrays=arrays)
