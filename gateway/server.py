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
import socket
import threading
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from engine.errors import CourtsideError
from gateway import codec, wire

log = logging.getLogger(__name__)

DROPPABLE_KINDS = frozenset({"samples", "camera"})
RequestHandler = Callable[[str, dict[str, Any]], Any]


class RequestError(CourtsideError):
    """Raised by a request handler to send a clean ``ok: false`` reply with this message."""


@dataclass
class ClientStats:
    """Per-client counters (frames), reported in status and by `StreamServer.client_stats`."""

    address: str
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
        self.topics: set[str] = set(wire.TOPICS)
        self._display: collections.deque[bytes] = collections.deque()
        self._reliable: collections.deque[bytes] = collections.deque()
        self._cond = threading.Condition()
        self._closed = False
        self._writer = threading.Thread(target=self._write_loop, name=f"gw-client-w-{address}", daemon=True)
        self._reader = threading.Thread(target=self._read_loop, name=f"gw-client-r-{address}", daemon=True)

    def start(self, hello: bytes) -> None:
        self.push(hello, droppable=False)
        self._writer.start()
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
                    while not self._closed and not self._reliable and not self._display:
                        self._cond.wait()
                    if self._closed:
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
        try:
            while True:
                msg = wire.recv_message(self.sock)
                if msg is None:
                    return
                self._handle(msg)
        except (OSError, wire.WireError) as exc:
            if not self._closed:
                log.info("client %s: %s", self.stats.address, exc)
        finally:
            self.close()

    def _handle(self, msg: codec.Message) -> None:
        if msg.kind == wire.SUBSCRIBE:
            topics = msg.header.get("topics")
            unknown = set(topics or ()) - set(wire.TOPICS)
            if not isinstance(topics, list) or unknown:
                self._reply(msg.header.get("id"), ok=False, error=f"unknown topics {sorted(unknown)}; valid: {list(wire.TOPICS)}")
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
            try:
                result = self.server.handler(action, args)
            except RequestError as exc:
                self._reply(request_id, ok=False, error=str(exc))
            except Exception as exc:  # a handler bug must not kill the session; report it to the caller
                log.exception("request %s failed", action)
                self._reply(request_id, ok=False, error=f"{type(exc).__name__}: {exc}")
            else:
                self._reply(request_id, ok=True, result=result)
        else:
            self._reply(msg.header.get("id"), ok=False, error=f"unknown message kind {msg.kind!r}")

    def _reply(self, request_id: Any, ok: bool, result: Any = None, error: str | None = None) -> None:
        header: dict[str, Any] = {"id": request_id, "ok": ok}
        if ok:
            header["result"] = result
        else:
            header["error"] = error
        self.push(wire.pack(wire.REPLY, header), droppable=False)

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

    ``handler(action, args) -> result`` serves control requests (it runs on the requesting client's reader
    thread; raise `RequestError` for a clean refusal). ``hello()`` returns the greeting header sent on connect.
    """

    def __init__(
        self,
        handler: RequestHandler,
        host: str = "127.0.0.1",
        port: int = 0,
        hello: Callable[[], dict[str, Any]] | None = None,
        display_queue_frames: int = 512,
        reliable_queue_limit: int = 10_000,
    ):
        self.handler = handler
        self.display_queue_frames = display_queue_frames
        self.reliable_queue_limit = reliable_queue_limit
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

    def _accept_loop(self) -> None:
        while self._running.is_set():
            try:
                sock, addr = self._listener.accept()
            except socket.timeout:
                continue
            except OSError:
                return
            sock.settimeout(None)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            session = _ClientSession(self, sock, f"{addr[0]}:{addr[1]}")
            with self._lock:
                self._sessions.append(session)
            hello = {"protocol": wire.PROTOCOL_VERSION, "topics": list(wire.TOPICS), **self._hello()}
            session.start(wire.pack(wire.SERVER_HELLO, hello))
            log.info("client connected from %s", session.stats.address)

    def _forget(self, session: _ClientSession) -> None:
        with self._lock:
            if session in self._sessions:
                self._sessions.remove(session)
                log.info("client %s disconnected", session.stats.address)

    def publish(self, kind: str, header: dict[str, Any] | None = None, arrays: dict[str, np.ndarray] | None = None) -> int:
        """Send one message to every client subscribed to ``kind``; returns how many clients it was queued for.

        Encodes once and only if someone listens, so an idle gateway spends nothing on display traffic."""
        with self._lock:
            targets = [s for s in self._sessions if kind in s.topics and not s.closed]
        if not targets:
            return 0
        data = wire.pack(kind, header, arrays)
        droppable = kind in DROPPABLE_KINDS
        for session in targets:
            session.push(data, droppable)
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
