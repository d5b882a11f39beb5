"""TCP framing between the gateway and its clients (see docs/gateway.md, "Wire format").

Each frame is ``u32 big-endian length`` followed by that many bytes of a `gateway.codec` body. Length-prefixing
(rather than a delimiter) lets binary numpy payloads pass untouched, and TCP already guarantees integrity.
"""
from __future__ import annotations

import select
import socket
import struct
import time
from typing import Any

import numpy as np

from engine.errors import CourtsideError
from gateway import codec

PROTOCOL_VERSION = 2  # 2: authentication (hello "auth" + "auth" request), roles
MAX_FRAME_BYTES = 64 << 20  # server -> client (thumbnails, sample batches)
MAX_REQUEST_BYTES = 1 << 20  # client -> server: requests are small JSON objects
READ_CHUNK_BYTES = 1 << 16
_U32 = struct.Struct(">I")

# Server -> client message kinds ("topics" a client can subscribe to).
TOPICS = ("samples", "status", "camera", "calibration", "recording", "event")
# Always delivered whatever the subscription: the greeting and replies to requests.
SERVER_HELLO = "hello"
REPLY = "reply"
# Client -> server kinds.
SUBSCRIBE = "subscribe"
REQUEST = "request"
AUTH = "auth"  # answer to the hello's challenge (gateway.auth)
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


class WireTimeout(WireError):
    """The peer started a frame (or owed the handshake) and did not finish it in time."""


class UndecodableFrame(WireError):
    """A whole frame arrived but its body is not a valid message. The stream is still in step, so a server can
    answer with an error reply and go on reading (issue 12: JSON nested 200 000 deep, absurd array shapes)."""


def _wait_readable(sock: socket.socket, deadline: float | None) -> None:
    """Block until ``sock`` has bytes (or EOF) to read; `WireTimeout` once ``deadline`` (monotonic) passes.
    ``deadline`` None waits for ever: an authenticated client may stay quiet as long as it likes."""
    pending = getattr(sock, "pending", None)  # a TLS channel may hold decrypted bytes already
    if pending is not None and pending():
        return
    remaining = None if deadline is None else deadline - time.monotonic()
    if remaining is not None and remaining <= 0:
        raise WireTimeout("peer too slow: frame or handshake not completed in time")
    try:
        ready = select.select([sock], [], [], remaining)[0]
    except ValueError:  # closed by another thread meanwhile (fileno -1): as recv on a closed socket would
        raise OSError("socket closed") from None
    if not ready:
        raise WireTimeout("peer too slow: frame or handshake not completed in time")


def _recv_exact(sock: socket.socket, n: int, deadline: float | None) -> bytes | None:
    """Read exactly ``n`` bytes by chunks, so memory grows with the bytes that really arrive, never with a length
    the peer merely announced (four bytes must not allocate 64 MiB). None on a clean EOF before the first byte."""
    buf = bytearray()
    read_some = getattr(sock, "read_some", None)  # gateway.tls.TlsChannel
    while len(buf) < n:
        if read_some is not None:
            try:
                chunk = read_some(min(n - len(buf), READ_CHUNK_BYTES), deadline)
            except TimeoutError:
                raise WireTimeout("peer too slow: frame not completed in time") from None
        else:
            _wait_readable(sock, deadline)
            chunk = sock.recv(min(n - len(buf), READ_CHUNK_BYTES))
        if not chunk:
            if not buf:
                return None
            raise WireError(f"connection closed mid-frame ({len(buf)} of {n} bytes)")
        buf += chunk
    return bytes(buf)


def recv_message(sock: socket.socket, *, max_frame_bytes: int = MAX_FRAME_BYTES, frame_timeout_s: float | None = None,
                 idle_deadline: float | None = None) -> codec.Message | None:
    """Block until one whole message arrives; None when the peer closed the connection cleanly.

    ``idle_deadline`` (monotonic, None = wait forever) bounds the wait for a frame to start; once it has started,
    the whole frame must arrive within ``frame_timeout_s``. Oversized, truncated or late frames raise `WireError`
    (the connection is then unusable); a complete frame that does not decode raises `UndecodableFrame`."""
    _wait_readable(sock, idle_deadline)
    started = time.monotonic()
    deadline = None if frame_timeout_s is None else started + frame_timeout_s
    prefix = _recv_exact(sock, 4, deadline)
    if prefix is None:
        return None
    (length,) = _U32.unpack(prefix)
    if length > max_frame_bytes:
        raise WireError(f"peer announced a {length}-byte frame (limit {max_frame_bytes})")
    body = _recv_exact(sock, length, deadline)
    if body is None:
        raise WireError("connection closed after a frame length")
    try:
        return codec.decode(body)
    except (codec.CodecError, RecursionError, ValueError, MemoryError) as exc:
        problem = "JSON nested too deeply" if isinstance(exc, RecursionError) else str(exc)[:200]
        raise UndecodableFrame(f"undecodable frame: {problem}") from None
