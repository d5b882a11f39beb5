"""Streaming server: many TCP clients, each with its own bounded queue, plus a request/reply control channel.

Why per-client queues with drop-oldest: a slow console must never stall acquisition or other clients. Display
data (``samples``, ``camera``) is dropped oldest-first when a client falls behind, and every drop is counted and
reported to that client in ``status``. Control traffic (replies, status, events, recording, calibration) is small
and never dropped; a client whose reliable backlog still grows past a hard limit is disconnected. Recording does
not go through here at all (see `gateway.recorder`), so nothing a client does can lose a recorded sample.
"""
from __future__ import annotations

import collections
import logging
import secrets
import socket
import ssl
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from engine.errors import CourtsideError
from gateway import auth, codec, wire
from gateway.tls import TlsChannel

log = logging.getLogger(__name__)

DROPPABLE_KINDS = frozenset({"samples", "camera"})
MAX_BAD_FRAMES = 10  # undecodable frames answered on one connection before it is dropped (no log flood)
# handler(action, args, role) -> result; the server has already checked that ``role`` may run ``action``
RequestHandler = Callable[[str, dict[str, Any], str], Any]


class RequestError(CourtsideError):
    """Raised by a request handler to send a clean ``ok: false`` reply with this message."""


@dataclass
class ClientStats:
    """Per-client counters (frames), reported in status and by `StreamServer.client_stats`."""

    address: str
    role: str | None = None  # None until authenticated
    sent: int = 0
    dropped: int = 0
    queued: int = 0
    requests: int = 0


class _ClientSession:
    """One connected client: a writer thread draining two queues and a reader thread serving requests."""

    def __init__(self, server: "StreamServer", sock: socket.socket, address: str):
        self.server = server
        self.sock = sock
        self.stats = ClientStats(address=address)
        self.connected_s = time.monotonic()
        self.nonce = secrets.token_bytes(auth.NONCE_BYTES)
        self.role: str | None = None if server.secrets.required else auth.OPERATOR
        self.stats.role = self.role
        # nothing is streamed to a connection before it has authenticated
        self.topics: set[str] = set(wire.TOPICS) if self.role else set()
        self._display: collections.deque[bytes] = collections.deque()
        self._reliable: collections.deque[bytes] = collections.deque()
        self._cond = threading.Condition()
        self._closed = False
        self._closing = False  # close once the reliable queue is sent
        self.bad_frames = 0
        self._writer = threading.Thread(target=self._write_loop, name=f"gw-client-w-{address}", daemon=True)
        self._reader = threading.Thread(target=self._read_loop, name=f"gw-client-r-{address}", daemon=True)

    def start(self, hello: bytes) -> None:
        """Queue the hello and start reading; the writer starts once any TLS handshake is done."""
        self.push(hello, droppable=False)
        self._reader.start()

    def push(self, data: bytes, droppable: bool) -> None:
        """Queue one framed message; never blocks. Drops the oldest display frame when the display queue is full."""
        with self._cond:
            if self._closed:
                return
            if droppable:
                if len(self._display) >= self.server.display_queue_frames:
                    self._display.popleft()
                    self.stats.dropped += 1
                self._display.append(data)
            else:
                if len(self._reliable) >= self.server.reliable_queue_limit:
                    log.warning("client %s is not reading; disconnecting", self.stats.address)
                    self._closed = True
                    self._cond.notify_all()
                    self._shutdown_socket()
                    return
                self._reliable.append(data)
            self.stats.queued = len(self._display) + len(self._reliable)
            self._cond.notify()

    def _shutdown_socket(self) -> None:
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass

    def _write_loop(self) -> None:
        try:
            while True:
                with self._cond:
                    while not self._closed and not self._reliable and not self._display and not self._closing:
                        self._cond.wait()
                    if self._closed or (self._closing and not self._reliable):
                        return
                    data = self._reliable.popleft() if self._reliable else self._display.popleft()
                    self.stats.queued = len(self._display) + len(self._reliable)
                self.sock.sendall(data)
                self.stats.sent += 1
        except OSError:
            pass
        finally:
            self.close()

    def _read_loop(self) -> None:
        server = self.server
        try:
            if isinstance(self.sock, TlsChannel):
                self.sock.handshake(server.handshake_timeout_s)
            self._writer.start()
            while not self._closed and not self._closing:
                # until authenticated, the whole handshake must finish within the timeout
                idle_deadline = None if self.role else self.connected_s + server.handshake_timeout_s
                try:
                    msg = wire.recv_message(self.sock, max_frame_bytes=server.max_request_bytes,
                                            frame_timeout_s=server.handshake_timeout_s, idle_deadline=idle_deadline)
                except wire.UndecodableFrame as exc:
                    self.bad_frames += 1
                    if self.bad_frames > MAX_BAD_FRAMES:
                        raise wire.WireError(f"{self.bad_frames} undecodable frames") from None
                    log.warning("client %s: %s", self.stats.address, exc)
                    self._reply(None, ok=False, error=str(exc))
                    continue
                if msg is None:
                    return
                self._handle(msg)
        except (OSError, wire.WireError) as exc:
            if not self._closed:
                log.warning("client %s: %s; disconnecting", self.stats.address, exc)
        except Exception:  # never a traceback per client thread: one line, then the connection closes
            log.exception("client %s: unexpected error; disconnecting", self.stats.address)
        finally:
            if self._closing:  # the writer sends the refusal, then closes; a peer that never reads is cut off
                timer = threading.Timer(self.server.handshake_timeout_s, self.close)
                timer.daemon = True
                timer.start()
            else:
                self.close()

    def _authenticate(self, msg: codec.Message) -> None:
        request_id = msg.header.get("id")
        try:
            client_nonce = bytes.fromhex(str(msg.header.get("nonce")))
        except ValueError:
            client_nonce = b""
        verified = (self.server.secrets.verify(msg.header.get("proof"), self.nonce, client_nonce)
                    if len(client_nonce) == auth.NONCE_BYTES else None)
        if verified is None:
            log.warning("client %s: authentication failed; disconnecting", self.stats.address)
            self._reply(request_id, ok=False, error="authentication failed (wrong secret?)")
            self.close_after_flush()
            return
        role, secret = verified
        if self.server.authenticated_clients() >= self.server.max_clients:
            self._reply(request_id, ok=False, error=f"gateway busy: {self.server.max_clients} clients connected (limit)")
            self.close_after_flush()
            return
        self.role = self.stats.role = role
        with self._cond:
            self.topics = set(wire.TOPICS)
        log.info("client %s authenticated as %s", self.stats.address, role)
        self._reply(request_id, ok=True, result={
            "role": role, "proof": auth.proof(secret, "server", self.nonce, client_nonce), **self.server.hello()})

    def _handle(self, msg: codec.Message) -> None:
        if self.role is None:
            if msg.kind == wire.AUTH:
                self._authenticate(msg)
            else:
                self._reply(msg.header.get("id"), ok=False, error="authenticate first: this gateway requires a secret")
                self.close_after_flush()
            return
        if msg.kind == wire.SUBSCRIBE:
            topics = msg.header.get("topics")
            unknown = set(topics) - set(wire.TOPICS) if isinstance(topics, list) else set()
            if not isinstance(topics, list) or unknown or not all(isinstance(t, str) for t in topics):
                self._reply(msg.header.get("id"), ok=False,
                            error=f"unknown topics {sorted(map(str, unknown))}; valid: {list(wire.TOPICS)}")
                return
            with self._cond:
                self.topics = set(topics)
            self._reply(msg.header.get("id"), ok=True, result={"topics": sorted(self.topics)})
        elif msg.kind == wire.REQUEST:
            self.stats.requests += 1
            request_id = msg.header.get("id")
            action = msg.header.get("action")
            args = msg.header.get("args") or {}
            if not isinstance(action, str) or not isinstance(args, dict):
                self._reply(request_id, ok=False, error="request needs a string 'action' and an object 'args'")
                return
            needed = auth.required_role(action, args)
            if not auth.permits(self.role, needed):
                log.info("client %s (%s) refused %r", self.stats.address, self.role, action)
                self._reply(request_id, ok=False, error=f"{action!r} needs the {needed} role; this connection is "
                            f"a {self.role}")
                return
            try:
                result = self.server.handler(action, args, self.role)
            except RequestError as exc:
                self._reply(request_id, ok=False, error=str(exc))
            except Exception as exc:  # a handler bug must not kill the session; report it to the caller
                log.exception("request %s failed", action)
                self._reply(request_id, ok=False, error=f"{type(exc).__name__}: {exc}")
            else:
                self._reply(request_id, ok=True, result=result)
        else:
            self._reply(msg.header.get("id"), ok=False, error=f"unknown message kind {msg.kind!r}"[:200])

    def _reply(self, request_id: Any, ok: bool, result: Any = None, error: str | None = None) -> None:
        header: dict[str, Any] = {"id": request_id, "ok": ok}
        if ok:
            header["result"] = result
        else:
            header["error"] = error
        self.push(wire.pack(wire.REPLY, header), droppable=False)

    def close_after_flush(self) -> None:
        """Stop reading; the writer sends what is queued (the refusal) and then closes."""
        with self._cond:
            self._closing = True
            self._cond.notify_all()

    def close(self) -> None:
        with self._cond:
            if self._closed and self.sock.fileno() == -1:
                return
            self._closed = True
            self._cond.notify_all()
        self._shutdown_socket()
        try:
            self.sock.close()
        except OSError:
            pass
        self.server._forget(self)

    @property
    def closed(self) -> bool:
        return self._closed


class StreamServer:
    """Accepts clients on ``host:port`` and fans published messages out to them.

    ``handler(action, args, role) -> result`` serves control requests (it runs on the requesting client's reader
    thread, after the server has checked the client's role may make that request; raise `RequestError` for a
    clean refusal). ``hello()`` returns the greeting fields for an authenticated (or loopback, unauthenticated)
    client. With ``secrets.required`` every connection must answer the challenge in its hello within
    ``handshake_timeout_s`` before it may do or receive anything (gateway.auth).
    """

    def __init__(
        self,
        handler: RequestHandler,
        host: str = "127.0.0.1",
        port: int = 0,
        hello: Callable[[], dict[str, Any]] | None = None,
        display_queue_frames: int = 512,
        reliable_queue_limit: int = 10_000,
        *,
        secrets: auth.Secrets = auth.Secrets(),
        max_clients: int = 32,
        max_pending: int = 8,
        handshake_timeout_s: float = 5.0,
        max_request_bytes: int = wire.MAX_REQUEST_BYTES,
        name: str = "courtside-gateway",
        tls: ssl.SSLContext | None = None,
    ):
        self.handler = handler
        self.tls = tls
        self.display_queue_frames = display_queue_frames
        self.reliable_queue_limit = reliable_queue_limit
        self.secrets = secrets
        self.max_clients = max_clients  # authenticated (or, without a secret, all) connections
        self.max_pending = max_pending  # connections still owing the challenge's answer
        self.handshake_timeout_s = handshake_timeout_s
        self.max_request_bytes = max_request_bytes
        self.name = name
        self.refused_connections = 0
        self._last_refusal_log_s = -1e9
        self._hello = hello or (lambda: {})
        self._sessions: list[_ClientSession] = []
        self._lock = threading.Lock()
        self._listener = socket.create_server((host, port), reuse_port=False)
        self._listener.settimeout(0.2)
        self._running = threading.Event()
        self._accept_thread = threading.Thread(target=self._accept_loop, name="gw-accept", daemon=True)

    @property
    def address(self) -> tuple[str, int]:
        """(host, port) actually bound (port 0 asks the OS for a free one)."""
        host, port = self._listener.getsockname()[:2]
        return host, port

    def start(self) -> "StreamServer":
        self._running.set()
        self._accept_thread.start()
        return self

    def hello(self) -> dict[str, Any]:
        """Greeting fields for a client that may see the gateway's state."""
        return {"protocol": wire.PROTOCOL_VERSION, "topics": list(wire.TOPICS), "gateway": self.name, **self._hello()}

    def _accept_loop(self) -> None:
        while self._running.is_set():
            try:
                sock, addr = self._listener.accept()
            except socket.timeout:
                continue
            except OSError:
                return
            address = f"{addr[0]}:{addr[1]}"
            with self._lock:
                full = sum(s.role is not None for s in self._sessions) >= self.max_clients
                pending = [s for s in self._sessions if s.role is None]
            if len(pending) >= self.max_pending:
                # handshakes are bounded too: the oldest unfinished one makes room (a real client answers the
                # challenge in milliseconds, so holding every slot would take a flood faster than that)
                self._log_limited(f"too many unauthenticated connections (limit {self.max_pending}); dropping "
                                  f"{pending[0].stats.address}")
                pending[0].close()
            if full:
                self.refused_connections += 1
                self._log_limited(f"refused client {address}: {self.max_clients} clients connected (limit); "
                                  f"{self.refused_connections} refused so far")
                if self.tls is None:
                    self._refuse(sock, f"gateway busy: {self.max_clients} clients connected (limit)")
                else:
                    sock.close()  # a TLS client could not read a plain refusal
                continue
            sock.settimeout(None)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            channel = sock if self.tls is None else TlsChannel(sock, self.tls, server_side=True)
            session = _ClientSession(self, channel, address)
            with self._lock:
                self._sessions.append(session)
            if session.role is None:
                hello = {"protocol": wire.PROTOCOL_VERSION, "gateway": self.name,
                         "auth": {"challenge": session.nonce.hex(), "method": "hmac-sha256"}}
            else:
                hello = {**self.hello(), "role": session.role}
            session.start(wire.pack(wire.SERVER_HELLO, hello))
            log.info("client connected from %s", session.stats.address)

    def _log_limited(self, message: str) -> None:
        """A warning at most once a second: a connection flood must not flood the log."""
        if time.monotonic() - self._last_refusal_log_s >= 1.0:
            self._last_refusal_log_s = time.monotonic()
            log.warning("%s", message)

    def authenticated_clients(self) -> int:
        with self._lock:
            return sum(s.role is not None for s in self._sessions)

    @staticmethod
    def _refuse(sock: socket.socket, reason: str) -> None:
        """Tell a client we cannot take why (one small frame, never blocking the accept loop), then close."""
        try:
            sock.setblocking(False)
            sock.send(wire.pack(wire.REPLY, {"id": None, "ok": False, "error": reason}))
        except OSError:
            pass
        finally:
            sock.close()

    def _forget(self, session: _ClientSession) -> None:
        with self._lock:
            if session in self._sessions:
                self._sessions.remove(session)
                log.info("client %s disconnected", session.stats.address)

    def publish(self, kind: str, header: dict[str, Any] | None = None, arrays: dict[str, np.ndarray] | None = None,
                viewer_header: dict[str, Any] | None = None) -> int:
        """Send one message to every client subscribed to ``kind``; returns how many clients it was queued for.

        Encodes once (twice with ``viewer_header``: what viewers get instead, e.g. status without other clients'
        addresses) and only if someone listens, so an idle gateway spends nothing on display traffic."""
        with self._lock:
            targets = [s for s in self._sessions if kind in s.topics and not s.closed and s.role is not None]
        if not targets:
            return 0
        data = wire.pack(kind, header, arrays)
        viewer_data = wire.pack(kind, viewer_header, arrays) if viewer_header is not None else data
        droppable = kind in DROPPABLE_KINDS
        for session in targets:
            session.push(viewer_data if session.role == auth.VIEWER else data, droppable)
        return len(targets)

    def client_stats(self) -> list[ClientStats]:
        with self._lock:
            return [ClientStats(**vars(s.stats)) for s in self._sessions]

    def close(self) -> None:
        self._running.clear()
        try:
            self._listener.close()
        except OSError:
            pass
        if self._accept_thread.is_alive():
            self._accept_thread.join(timeout=2)
        with self._lock:
            sessions = list(self._sessions)
        for session in sessions:
            session.close()
