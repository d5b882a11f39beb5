"""Streaming server: many TCP clients, each with its own bounded queue, plus a request/reply control channel.

Why per-client queues with drop-oldest: a slow console must never stall acquisition or other clients. Display
data (``samples``, ``camera``) is dropped oldest-first when a client falls behind, and every drop is counted and
reported to that client in ``status``. Control traffic (replies, status, events, recording, calibration) is small
and never dropped; a client whose reliable backlog still grows past a hard limit is disconnected. Recording does
not go through here at all (see `gateway.recorder`), so nothing a client does can lose a recorded sample.

Memory is bounded in bytes, not frames (issue 22: viewers sending ``status`` without reading grew the gateway by
139 MB in 13 s under a 10 000-frame bound): each client's display and reliable queues have a byte limit, and all
clients together share `StreamServer.queue_budget_bytes`. Over its display limit or the budget a client loses its
oldest display frames; a reliable frame that does not fit disconnects that client (it is not reading).

Viewers never lock the operator out (issue 22): when the gateway is full, an operator authenticating evicts the
viewer that connected first, and a full gateway still accepts connections (to authenticate) while a viewer holds
a slot. Every field of every client message is type-checked before use (`gateway.request_schema`).
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
from gateway import auth, codec, request_schema, wire
from gateway.tls import TlsChannel

log = logging.getLogger(__name__)

DROPPABLE_KINDS = frozenset({"samples", "camera"})
MAX_BAD_FRAMES = 10  # undecodable frames answered on one connection before it is dropped (no log flood)
DISPLAY_QUEUE_BYTES = 4 << 20  # per client: ~4 s of six 100 Hz sensors plus thumbnails; older frames are dropped
RELIABLE_QUEUE_BYTES = 2 << 20  # per client: replies/status/events; ~100 status snapshots, then the client goes
QUEUE_BUDGET_BYTES = 48 << 20  # every client's queues together: the most a small board spends on clients
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
    queued_bytes: int = 0
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
        self._display_bytes = 0
        self._reliable_bytes = 0
        self._cond = threading.Condition()
        self._closed = False
        self._closing = False  # close once the reliable queue is sent
        self.bad_frames = 0
        self.evicted = False  # a viewer leaving to make room for an operator no longer holds a slot
        self._writer = threading.Thread(target=self._write_loop, name=f"gw-client-w-{address}", daemon=True)
        self._reader = threading.Thread(target=self._read_loop, name=f"gw-client-r-{address}", daemon=True)

    def start(self, hello: bytes) -> None:
        """Queue the hello and start reading; the writer starts once any TLS handshake is done."""
        self.push(hello, droppable=False)
        self._reader.start()

    def push(self, data: bytes, droppable: bool) -> None:
        """Queue one framed message; never blocks. A display frame makes room by dropping this client's oldest
        display frames (or is dropped itself); a reliable frame that does not fit this client's limit
        disconnects it, and when the process budget is full the client with the largest backlog goes first."""
        server, size = self.server, len(data)
        if not droppable and not server.fits(size):
            server.evict_largest_backlog()  # outside our lock: it closes another session
        with self._cond:
            if self._closed:
                return
            if droppable:
                while self._display and (len(self._display) >= server.display_queue_frames
                                         or self._display_bytes + size > server.display_queue_bytes
                                         or not server.fits(size, display=True)):
                    old = len(self._display.popleft())
                    self._display_bytes -= old
                    server.release_bytes(old)
                    self.stats.dropped += 1
                if size > server.display_queue_bytes or not server.reserve_bytes(size, display=True):
                    self.stats.dropped += 1  # nothing of ours left to drop: the new frame goes
                    self._update_queued()
                    return
                self._display.append(data)
                self._display_bytes += size
            else:
                if (len(self._reliable) >= server.reliable_queue_limit
                        or self._reliable_bytes + size > server.reliable_queue_bytes or not server.reserve_bytes(size)):
                    log.warning("client %s is not reading (%d bytes queued); disconnecting", self.stats.address,
                                self._display_bytes + self._reliable_bytes + size)
                    self._closed = True
                    self._release_queues()
                    self._cond.notify_all()
                    self._shutdown_socket()
                    return
                self._reliable.append(data)
                self._reliable_bytes += size
            self._update_queued()
            self._cond.notify()

    def _update_queued(self) -> None:
        self.stats.queued = len(self._display) + len(self._reliable)
        self.stats.queued_bytes = self._display_bytes + self._reliable_bytes

    def _release_queues(self) -> None:
        """Give this client's queued bytes back to the server's budget (called with ``_cond`` held, once closed)."""
        self.server.release_bytes(self._display_bytes + self._reliable_bytes)
        self._display.clear()
        self._reliable.clear()
        self._display_bytes = self._reliable_bytes = 0
        self._update_queued()

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
                    if self._reliable:
                        data = self._reliable.popleft()
                        self._reliable_bytes -= len(data)
                    else:
                        data = self._display.popleft()
                        self._display_bytes -= len(data)
                    self.server.release_bytes(len(data))
                    self._update_queued()
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
        problem = request_schema.auth_problem(msg.header)
        verified = None if problem else self.server.secrets.verify(
            msg.header["proof"], self.nonce, bytes.fromhex(msg.header["nonce"]))
        if verified is None:
            log.warning("client %s: authentication failed; disconnecting", self.stats.address)
            self._reply(request_id, ok=False, error=problem or "authentication failed (wrong secret?)")
            self.close_after_flush()
            return
        role, secret = verified
        if not self.server.make_room_for(role):
            self._reply(request_id, ok=False, error=f"gateway busy: {self.server.max_clients} clients connected (limit)")
            self.close_after_flush()
            return
        self.role = self.stats.role = role
        with self._cond:
            self.topics = set(wire.TOPICS)
        log.info("client %s authenticated as %s", self.stats.address, role)
        self._reply(request_id, ok=True, result={
            "role": role, "proof": auth.proof(secret, "server", self.nonce, bytes.fromhex(msg.header["nonce"])),
            **self.server.hello()})

    def _handle(self, msg: codec.Message) -> None:
        problem = request_schema.id_problem(msg.header)
        request_id = None if problem else msg.header.get("id")
        if self.role is None:
            if msg.kind == wire.AUTH and not problem:
                self._authenticate(msg)
            else:
                self._reply(request_id, ok=False, error=problem or "authenticate first: this gateway requires a secret")
                self.close_after_flush()
            return
        if problem:
            self._reply(None, ok=False, error=problem)
        elif msg.kind == wire.SUBSCRIBE:
            problem = request_schema.topics_problem(msg.header)
            if problem:
                self._reply(request_id, ok=False, error=problem)
                return
            with self._cond:
                self.topics = set(msg.header["topics"])
            self._reply(request_id, ok=True, result={"topics": sorted(self.topics)})
        elif msg.kind == wire.REQUEST:
            self.stats.requests += 1
            problem = request_schema.request_problem(msg.header)
            if problem:
                self._reply(request_id, ok=False, error=problem)
                return
            self._serve(request_id, msg.header["action"], msg.header.get("args") or {})
        else:
            self._reply(request_id, ok=False, error=f"unknown message kind {msg.kind!r}"[:200])

    def _serve(self, request_id: Any, action: str, args: dict[str, Any]) -> None:
        """Run one well-formed request after checking this connection's role may make it."""
        needed = auth.required_role(action, args)
        if not auth.permits(self.role or auth.VIEWER, needed):
            log.info("client %s (%s) refused %r", self.stats.address, self.role, action[:40])
            self._reply(request_id, ok=False, error=f"{action[:40]!r} needs the {needed} role; this connection is "
                        f"a {self.role}")
            return
        try:
            result = self.server.handler(action, args, self.role or auth.VIEWER)
        except RequestError as exc:
            self._reply(request_id, ok=False, error=str(exc))
        except Exception as exc:  # a handler bug must not kill the session; report it to the caller
            log.exception("request %s failed", action[:40])
            self._reply(request_id, ok=False, error=f"{type(exc).__name__}: {exc}")
        else:
            self._reply(request_id, ok=True, result=result)

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
            self._release_queues()
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
        display_queue_bytes: int = DISPLAY_QUEUE_BYTES,
        reliable_queue_bytes: int = RELIABLE_QUEUE_BYTES,
        queue_budget_bytes: int = QUEUE_BUDGET_BYTES,
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
        self.display_queue_bytes = display_queue_bytes
        self.reliable_queue_bytes = reliable_queue_bytes
        self.queue_budget_bytes = queue_budget_bytes
        self._queued_bytes = 0  # all clients' queues together, <= queue_budget_bytes
        self._peak_queued_bytes = 0  # high-water mark: a backlog that lives for microseconds still shows here
        self._budget_lock = threading.Lock()
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
                authenticated = [s for s in self._sessions if s.role is not None and not s.evicted]
                # while a viewer holds a slot, a newcomer may be an operator who evicts it (make_room_for)
                full = (len(authenticated) >= self.max_clients
                        and not any(s.role == auth.VIEWER for s in authenticated))
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

    def _budget(self, display: bool) -> int:
        # display frames may use half the budget, so replies and events for clients that read always find room
        return self.queue_budget_bytes // 2 if display else self.queue_budget_bytes

    def fits(self, size: int, display: bool = False) -> bool:
        """Whether ``size`` more queued bytes would stay within the budget (a hint; `reserve_bytes` decides)."""
        return self._queued_bytes + size <= self._budget(display)

    def reserve_bytes(self, size: int, display: bool = False) -> bool:
        """Count ``size`` queued bytes against the process budget; False (nothing counted) if over it."""
        with self._budget_lock:
            if self._queued_bytes + size > self._budget(display):
                return False
            self._queued_bytes += size
            self._peak_queued_bytes = max(self._peak_queued_bytes, self._queued_bytes)
            return True

    def evict_largest_backlog(self) -> None:
        """The budget is full: disconnect the client with the most bytes queued (one that is not reading)."""
        with self._lock:
            sessions = [s for s in self._sessions if not s.closed]
        if sessions:
            victim = max(sessions, key=lambda s: s.stats.queued_bytes)
            self._log_limited(f"client queues reached the {self.queue_budget_bytes}-byte budget; disconnecting "
                              f"{victim.stats.address} ({victim.stats.queued_bytes} bytes queued)")
            victim.close()

    def release_bytes(self, size: int) -> None:
        with self._budget_lock:
            self._queued_bytes -= size

    @property
    def queued_bytes(self) -> int:
        """Bytes queued for all clients now (never above ``queue_budget_bytes``)."""
        return self._queued_bytes

    @property
    def peak_queued_bytes(self) -> int:
        """The most bytes ever queued for all clients together (the budget's high-water mark)."""
        return self._peak_queued_bytes

    def make_room_for(self, role: str) -> bool:
        """Whether a client just authenticated as ``role`` may stay. At the limit an operator evicts the viewer
        that connected first (told why in an event): viewers can never lock the operator out (issue 22)."""
        with self._lock:
            authenticated = [s for s in self._sessions if s.role is not None and not s.closed and not s.evicted]
            viewers = [s for s in authenticated if s.role == auth.VIEWER]
        if len(authenticated) < self.max_clients:
            return True
        if role != auth.OPERATOR or not viewers:
            return False
        victim = min(viewers, key=lambda s: s.connected_s)
        log.warning("gateway full (%d clients): viewer %s disconnected to make room for an operator",
                    self.max_clients, victim.stats.address)
        victim.evicted = True
        victim.push(wire.pack("event", {"t_host_s": time.monotonic(), "level": "warning", "source": "gateway",
                                        "message": "disconnected: the gateway is full and an operator needs this "
                                                   "viewer's slot"}), False)
        victim.close_after_flush()
        return True

    def authenticated_clients(self) -> int:
        with self._lock:
            return sum(s.role is not None and not s.evicted for s in self._sessions)

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
