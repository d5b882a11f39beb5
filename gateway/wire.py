"""TCP framing between the gateway and its clients (see docs/gateway.md, "Wire format").

Each frame is ``u32 big-endian length`` followed by that many bytes of a `gateway.codec` body. Length-prefixing
(rather than a delimiter) lets binary numpy payloads pass untouched, and TCP already guarantees integrity.
"""
from __future__ import annotations

import socket
import struct
from typing import Any

import numpy as np

from engine.errors import CourtsideError
from gateway import codec

PROTOCOL_VERSION = 1
MAX_FRAME_BYTES = 64 << 20
_U32 = struct.Struct(">I")

# Server -> client message kinds ("topics" a client can subscribe to).
TOPICS = ("samples", "status", "camera", "calibration", "recording", "event")
# Always delivered whatever the subscription: the greeting and replies to requests.
SERVER_HELLO = "hello"
REPLY = "reply"
# Client -> server kinds.
SUBSCRIBE = "subscribe"
REQUEST = "request"
# Request actions the server understands (args in docs/gateway.md).
ACTIONS = (
    "list_stations",
    "status",
    "start_recording",
    "stop_recording",
    "station_command",
    "calibration",
    "ping",
)


class WireError(CourtsideError, ConnectionError):
    """The peer sent something that is not a valid frame (too long, undecodable)."""


def frame(body: bytes) -> bytes:
    """Prefix ``body`` with its length."""
    if len(body) > MAX_FRAME_BYTES:
        raise WireError(f"frame of {len(body)} bytes exceeds the {MAX_FRAME_BYTES}-byte limit")
    return _U32.pack(len(body)) + body


def pack(kind: str, header: dict[str, Any] | None = None, arrays: dict[str, np.ndarray] | None = None) -> bytes:
    """Encode and frame one message, ready for ``sock.sendall``."""
    return frame(codec.encode(kind, header, arrays))


def _recv_exact(sock: socket.socket, n: int) -> bytes | None:
    """Read exactly ``n`` bytes; None on a clean EOF before the first byte."""
    buf = bytearray(n)
    view = memoryview(buf)
    got = 0
    while got < n:
        k = sock.recv_into(view[got:], n - got)
        if k == 0:
            if got == 0:
                return None
            raise WireError(f"connection closed mid-frame ({got} of {n} bytes)")
        got += k
    return bytes(buf)


def recv_message(sock: socket.socket) -> codec.Message | None:
    """Block until one whole message arrives; None when the peer closed the connection cleanly."""
    prefix = _recv_exact(sock, 4)
    if prefix is None:
        return None
    (length,) = _U32.unpack(prefix)
    if length > MAX_FRAME_BYTES:
        raise WireError(f"peer announced a {length}-byte frame (limit {MAX_FRAME_BYTES})")
    body = _recv_exact(sock, length)
    if body is None:
        raise WireError("connection closed after a frame length")
    try:
        return codec.decode(body)
    except codec.CodecError as exc:
        raise WireError(f"undecodable frame: {exc}") from exc


def parse_hostport(text: str, default_host: str = "127.0.0.1") -> tuple[str, int]:
    """``"host:port"`` or ``":port"`` or ``"port"`` -> (host, port)."""
    host, _, port = text.rpartition(":")
    try:
        return (host or default_host), int(port)
    except ValueError as exc:
        raise ValueError(f"listen address {text!r} is not host:port") from exc
