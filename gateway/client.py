"""`GatewayClient`: what the console (or any script) uses to talk to a running gateway.

Plain sockets and one reader thread, no Qt: the console wraps it and marshals callbacks onto its own thread.
Incoming messages are delivered two ways, use either or both:

* listeners: ``client.add_listener("samples", fn)`` calls ``fn(message)`` on the reader thread;
* a bounded inbox: ``client.get(timeout)`` / ``client.drain()`` (oldest dropped and counted if nobody reads it).

Requests (``start_recording``, ``station_command`` ...) block until the matching reply arrives and raise
`GatewayRequestError` when the gateway refuses. Wire format: docs/gateway.md.

Authentication: a gateway with a secret greets with a challenge; `connect` answers it with ``secret`` (bytes,
from `gateway.auth.client_secret`: a file or the environment, never the command line) and checks the gateway's
answer in turn. The role the secret grants (operator / viewer) is ``client.role``.
"""
from __future__ import annotations

import collections
import hmac
import itertools
import logging
import secrets
import socket
import ssl
import threading
import time
from typing import Any, Callable, Iterable

from engine.errors import CourtsideError
from gateway import auth, wire
from gateway.codec import Message
from gateway.tls import TlsChannel

log = logging.getLogger(__name__)

Listener = Callable[[Message], None]


class GatewayRequestError(CourtsideError, RuntimeError):
    """The gateway answered a request with ``ok: false`` (message = the gateway's reason)."""


class GatewayClient:
    """A connection to one gateway. Thread-safe; usable as a context manager.

    Example::

        with GatewayClient("127.0.0.1", 7766) as gw:
            gw.subscribe(["samples", "status"])
            gw.add_listener("samples", lambda m: print(m["station"], m["sensor"], m["acc_g"].shape))
            print(gw.list_stations())
            gw.start_recording("rally-01")
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 7766, *, secret: bytes | None = None,
                 tls: ssl.SSLContext | None = None, inbox_size: int = 10_000):
        self.host = host
        self.tls = tls
        self.port = port
        self.role: str | None = None
        self.server_hello: dict[str, Any] = {}
        self._secret = secret
        self._refusal: str | None = None
        self.inbox_dropped = 0
        self._inbox: collections.deque[Message] = collections.deque(maxlen=inbox_size)
        self._inbox_cond = threading.Condition()
        self._listeners: dict[str, list[Listener]] = collections.defaultdict(list)
        self._listeners_lock = threading.Lock()
        self._pending: dict[int, tuple[threading.Event, list[Message]]] = {}
        self._pending_lock = threading.Lock()
        self._ids = itertools.count(1)
        self._send_lock = threading.Lock()
        self._sock: Any = None  # socket.socket or gateway.tls.TlsChannel
        self._reader: threading.Thread | None = None
        self._hello_event = threading.Event()
        self._closed = threading.Event()

    # -- connection -------------------------------------------------------------------------------------------
    def connect(self, timeout_s: float = 5.0) -> "GatewayClient":
        """Open the TCP connection, wait for the gateway's hello and authenticate if it asks to.

        Raises ConnectionError when unreachable or refused (busy), `gateway.auth.AuthenticationError` when the
        gateway wants a secret we lack or rejects ours (or cannot prove it holds it)."""
        sock: Any = socket.create_connection((self.host, self.port), timeout=timeout_s)
        sock.settimeout(None)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if self.tls is not None:
            sock = TlsChannel(sock, self.tls, server_side=False, server_hostname=self.host)
            try:
                sock.handshake(timeout_s)
            except BaseException:
                sock.close()
                raise
        self._sock = sock
        self.server_hello, self._refusal, self.role = {}, None, None  # a reconnect starts from scratch
        self._closed.clear()
        self._hello_event.clear()
        self._reader = threading.Thread(target=self._read_loop, name="gw-client-reader", daemon=True)
        self._reader.start()
        if not self._hello_event.wait(timeout_s) or not self.server_hello:
            self.close()
            if self._refusal:
                raise ConnectionError(f"gateway {self.host}:{self.port} refused the connection: {self._refusal}")
            hint = "" if self.tls is not None else " (a TLS gateway waits for a TLS handshake: connect with TLS, " \
                "e.g. `courtside console --tls-ca cert.pem`)"
            raise ConnectionError(f"no hello from gateway {self.host}:{self.port} within {timeout_s} s{hint}")
        challenge = self.server_hello.get("auth")
        if challenge is None:
            self.role = self.server_hello.get("role", auth.OPERATOR)
            return self
        try:
            if not isinstance(challenge, dict) or not isinstance(challenge.get("challenge"), str):
                raise auth.AuthenticationError(f"gateway {self.host}:{self.port} sent a malformed challenge")
            self._authenticate(challenge["challenge"], timeout_s)
        except BaseException:
            self.close()
            raise
        return self

    def _authenticate(self, challenge_hex: str, timeout_s: float) -> None:
        where = f"gateway {self.host}:{self.port}"
        if self._secret is None:
            raise auth.AuthenticationError(
                f"{where} requires authentication: give the secret file (--secret-file, or "
                f"${auth.SECRET_FILE_ENV})")
        try:
            server_nonce = bytes.fromhex(challenge_hex)
        except ValueError:
            raise auth.AuthenticationError(f"{where} sent a malformed challenge") from None
        client_nonce = secrets.token_bytes(auth.NONCE_BYTES)
        try:
            result = self._send(wire.AUTH, {"nonce": client_nonce.hex(),
                                            "proof": auth.proof(self._secret, "client", server_nonce, client_nonce)},
                                timeout_s)
        except GatewayRequestError as exc:
            raise auth.AuthenticationError(f"{where}: {exc}") from None
        expected = auth.proof(self._secret, "server", server_nonce, client_nonce)
        proof = result.get("proof") if isinstance(result, dict) else None
        # compare_digest raises TypeError on non-ASCII text: an impostor's odd proof must still be one clean error
        if not isinstance(proof, str) or not proof.isascii() or not hmac.compare_digest(proof, expected):
            raise auth.AuthenticationError(f"{where} could not prove it holds the secret (an impostor?)")
        if result.get("role") not in auth.ROLES:
            raise auth.AuthenticationError(f"{where} granted an unknown role {str(result.get('role'))[:40]!r}")
        self.role = str(result["role"])
        self.server_hello = {k: v for k, v in result.items() if k != "proof"}

    @property
    def connected(self) -> bool:
        return self._sock is not None and not self._closed.is_set()

    def close(self) -> None:
        self._closed.set()
        sock, self._sock = self._sock, None
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            sock.close()
        if self._reader is not None and self._reader is not threading.current_thread():
            self._reader.join(timeout=2)
        self._fail_pending("connection closed")

    def __enter__(self) -> "GatewayClient":
        return self.connect() if not self.connected else self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- receiving --------------------------------------------------------------------------------------------
    def add_listener(self, kind: str, callback: Listener) -> None:
        """Call ``callback(message)`` on the reader thread for every message of ``kind`` ("*" = all kinds)."""
        with self._listeners_lock:
            self._listeners[kind].append(callback)

    def remove_listener(self, kind: str, callback: Listener) -> None:
        with self._listeners_lock:
            if callback in self._listeners.get(kind, []):
                self._listeners[kind].remove(callback)

    def get(self, timeout_s: float | None = None, kinds: Iterable[str] | None = None) -> Message | None:
        """Next inbox message (optionally only of ``kinds``; others are discarded); None on timeout."""
        wanted = set(kinds) if kinds is not None else None
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self._inbox_cond:
            while True:
                while self._inbox:
                    msg = self._inbox.popleft()
                    if wanted is None or msg.kind in wanted:
                        return msg
                remaining = None if deadline is None else deadline - time.monotonic()
                if (remaining is not None and remaining <= 0) or self._closed.is_set():
                    return None
                self._inbox_cond.wait(remaining)

    def drain(self) -> list[Message]:
        """Everything currently in the inbox, oldest first."""
        with self._inbox_cond:
            items = list(self._inbox)
            self._inbox.clear()
        return items

    def _read_loop(self) -> None:
        sock = self._sock
        try:
            while sock is not None and not self._closed.is_set():
                msg = wire.recv_message(sock)
                if msg is None:
                    break
                self._dispatch(msg)
        except (OSError, wire.WireError) as exc:
            if not self._closed.is_set():
                log.warning("gateway connection lost: %s", exc)
        finally:
            self._closed.set()
            self._hello_event.set()  # a connect() still waiting for the hello learns at once
            with self._inbox_cond:
                self._inbox_cond.notify_all()
            self._fail_pending("connection lost")

    def _dispatch(self, msg: Message) -> None:
        if msg.kind == wire.SERVER_HELLO:
            self.server_hello = msg.header
            self._hello_event.set()
            return
        if msg.kind == wire.REPLY and msg.header.get("id") is None and not self.server_hello:
            self._refusal = str(msg.header.get("error"))  # refused before any hello (e.g. too many clients)
            self._hello_event.set()
            return
        if msg.kind == wire.REPLY:
            with self._pending_lock:
                waiter = self._pending.pop(msg.header.get("id"), None)
            if waiter is not None:
                waiter[1].append(msg)
                waiter[0].set()
            return
        with self._listeners_lock:
            callbacks = list(self._listeners.get(msg.kind, ())) + list(self._listeners.get("*", ()))
        for callback in callbacks:
            try:
                callback(msg)
            except Exception:  # a faulty listener must not kill the connection
                log.exception("listener for %s failed", msg.kind)
        with self._inbox_cond:
            if len(self._inbox) == self._inbox.maxlen:
                self.inbox_dropped += 1
            self._inbox.append(msg)
            self._inbox_cond.notify_all()

    # -- requests ---------------------------------------------------------------------------------------------
    def _send(self, kind: str, header: dict[str, Any], timeout_s: float) -> Any:
        sock = self._sock
        if sock is None or self._closed.is_set():
            raise ConnectionError("not connected to a gateway")
        request_id = next(self._ids)
        event = threading.Event()
        box: list[Message] = []
        with self._pending_lock:
            self._pending[request_id] = (event, box)
        with self._send_lock:
            sock.sendall(wire.pack(kind, {"id": request_id, **header}))
        if not event.wait(timeout_s):
            with self._pending_lock:
                self._pending.pop(request_id, None)
            raise TimeoutError(f"gateway did not answer {header.get('action', kind)!r} within {timeout_s} s")
        if not box:
            raise ConnectionError("connection closed before the gateway replied")
        reply = box[0]
        if not reply.header.get("ok"):
            raise GatewayRequestError(str(reply.header.get("error")))
        return reply.header.get("result")

    def _fail_pending(self, reason: str) -> None:
        with self._pending_lock:
            waiters = list(self._pending.values())
            self._pending.clear()
        for event, _ in waiters:
            event.set()

    def request(self, action: str, /, timeout_s: float = 5.0, **args: Any) -> Any:
        """Send a control request and return the gateway's ``result`` (see docs/gateway.md for actions)."""
        return self._send(wire.REQUEST, {"action": action, "args": args}, timeout_s)

    def subscribe(self, topics: Iterable[str], timeout_s: float = 5.0) -> list[str]:
        """Receive only these topics (subset of `gateway.wire.TOPICS`; all by default)."""
        return self._send(wire.SUBSCRIBE, {"topics": list(topics)}, timeout_s)["topics"]

    def list_stations(self) -> list[dict[str, Any]]:
        return self.request("list_stations")

    def status(self) -> dict[str, Any]:
        """One status snapshot now (the same content as the periodic ``status`` messages)."""
        return self.request("status")

    def start_recording(self, take: str) -> dict[str, Any]:
        return self.request("start_recording", take=take)

    def stop_recording(self) -> dict[str, Any]:
        return self.request("stop_recording")

    def station_command(self, station: str, command: str, /, **args: Any) -> Any:
        """E.g. ``station_command("st0", "identify", sensor=3)`` or ``("st0", "set_rate", rate_hz=200)``."""
        return self.request("station_command", station=station, command=command, args=args)

    def calibration(self, action: str, /, **args: Any) -> Any:
        """Drive the calibration workflow (actions defined by gateway/calibration, see docs/camera-calibration.md)."""
        return self.request("calibration", action=action, args=args)
