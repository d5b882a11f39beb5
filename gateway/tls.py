"""TLS for the gateway's TCP link, full duplex across two threads (stdlib ``ssl`` with memory BIOs).

Why not ``ssl.SSLSocket``: every connection here has a reader thread and a writer thread on the same socket, and
OpenSSL objects must not be used by two threads at once. With an ``SSLObject`` over two ``MemoryBIO``s we do the
socket I/O ourselves and hold a lock only around the (fast, non-blocking) TLS bookkeeping: the reader never
blocks the writer while it waits for bytes. A second lock orders ciphertext on the wire. Reads take a deadline,
so a peer that stalls mid-record is cut off like one that stalls mid-frame (`gateway.wire`).

`TlsChannel` offers what `gateway.wire` and the server/client use of a socket: ``read_some``, ``sendall``,
``fileno``, ``shutdown``, ``close``.
"""
from __future__ import annotations

import select
import socket
import ssl
import threading
import time

from engine.errors import CourtsideError


class TlsError(CourtsideError, ConnectionError):
    """The TLS handshake failed or timed out (wrong certificate, not TLS, too slow)."""


class TlsChannel:
    """One TLS connection over a connected plain socket."""

    def __init__(self, sock: socket.socket, context: ssl.SSLContext, *, server_side: bool,
                 server_hostname: str | None = None) -> None:
        self.sock = sock
        self._incoming = ssl.MemoryBIO()
        self._outgoing = ssl.MemoryBIO()
        self._tls = context.wrap_bio(self._incoming, self._outgoing, server_side=server_side,
                                     server_hostname=server_hostname if context.check_hostname else None)
        self._lock = threading.Lock()  # the SSLObject and its BIOs
        self._send_lock = threading.Lock()  # ciphertext leaves in the order it was produced
        self._eof = False

    # -- plumbing -----------------------------------------------------------------------------------------------
    def _flush(self) -> None:
        with self._send_lock:
            with self._lock:
                data = self._outgoing.read()
            if data:
                self.sock.sendall(data)

    def _fill(self, deadline: float | None) -> bool:
        """Move ciphertext from the socket into the TLS object; False on EOF. Raises TimeoutError at the deadline."""
        if deadline is not None:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not select.select([self.sock], [], [], remaining)[0]:
                raise TimeoutError("TLS peer too slow")
        data = self.sock.recv(1 << 16)
        if not data:
            self._eof = True
            return False
        with self._lock:
            self._incoming.write(data)
        return True

    def handshake(self, timeout_s: float) -> None:
        """Complete the TLS handshake within ``timeout_s``; `TlsError` says why not."""
        deadline = time.monotonic() + timeout_s
        try:
            while True:
                with self._lock:
                    try:
                        self._tls.do_handshake()
                        done = True
                    except ssl.SSLWantReadError:
                        done = False
                self._flush()
                if done:
                    return
                if not self._fill(deadline):
                    raise TlsError("connection closed during the TLS handshake")
        except ssl.SSLError as exc:
            raise TlsError(f"TLS handshake failed: {exc.reason or exc}") from None
        except TimeoutError:
            raise TlsError(f"TLS handshake not completed within {timeout_s} s") from None

    # -- the socket-like interface ------------------------------------------------------------------------------
    def read_some(self, max_bytes: int, deadline: float | None = None) -> bytes:
        """Up to ``max_bytes`` of plaintext (at least one byte); b"" at the end of the stream."""
        while True:
            with self._lock:
                try:
                    return self._tls.read(max_bytes)
                except ssl.SSLWantReadError:
                    pass
                except ssl.SSLZeroReturnError:
                    return b""
            self._flush()  # reading can produce records to send (e.g. TLS 1.3 key updates)
            if self._eof or not self._fill(deadline):
                return b""

    def pending(self) -> int:
        """Bytes readable without waiting for the socket (decrypted, or ciphertext not yet decrypted)."""
        with self._lock:
            return self._tls.pending() + self._incoming.pending

    def sendall(self, data: bytes) -> None:
        with self._lock:
            self._tls.write(data)
        self._flush()

    def fileno(self) -> int:
        return self.sock.fileno()

    def shutdown(self, how: int) -> None:
        self.sock.shutdown(how)

    def close(self) -> None:
        self.sock.close()
