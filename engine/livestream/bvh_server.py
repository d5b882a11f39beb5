"""BVH over TCP in the Axis Neuron / Axis Studio (Perception Neuron) "BVH string" broadcast convention.

Axis acts as a TCP server (default port 7001) and every connected client (the Neuron plugins for Unity, Unreal,
MotionBuilder, Blender add-ons) receives one text line per frame: ``0 <avatar name> v1 v2 ... vN ||`` with the
frame's BVH channel values (root position, then every joint's rotation in degrees, in the hierarchy's order).
The hierarchy itself is not sent: the client loads it from a BVH file of the same skeleton (`courtside
synthesize -o out.bvh` writes one). This server does the same, bound to 127.0.0.1 unless told otherwise.

Why a plain socket server: the convention is one line per frame over TCP, so a thread that accepts clients and a
lock-protected client list is all it needs; a slow client is dropped rather than allowed to stall synthesis."""
from __future__ import annotations

import socket
import threading
import time
from typing import Any

import numpy as np

DEFAULT_PORT = 7001
SEND_TIMEOUT_S = 0.5


def frame_line(values: np.ndarray, avatar: str = "Avatar00", avatar_index: int = 0) -> bytes:
    """One broadcast line: ``"<index> <avatar> v1 ... vN ||\\n"`` (values to 6 decimals)."""
    return (f"{avatar_index} {avatar} " + " ".join(f"{v:.6f}" for v in np.asarray(values, float)) + " ||\n").encode()


class BvhBroadcastServer:
    """Accepts clients on ``host:port`` (port 0 = any free port) and sends them every frame given to
    :meth:`send_frame`. Use as a context manager."""

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, avatar: str = "Avatar00") -> None:
        self.avatar = avatar
        self._sock = socket.create_server((host, port))
        self._sock.settimeout(0.1)
        self._clients: list[socket.socket] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._accept, name="bvh-broadcast-accept", daemon=True)
        self._thread.start()
        self.frames_sent = 0

    @property
    def address(self) -> tuple[str, int]:
        return self._sock.getsockname()[:2]

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._sock.accept()
            except (TimeoutError, socket.timeout):
                continue
            except OSError:
                return
            conn.settimeout(SEND_TIMEOUT_S)
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._lock:
                self._clients.append(conn)

    @property
    def n_clients(self) -> int:
        with self._lock:
            return len(self._clients)

    def wait_for_clients(self, n: int = 1, timeout_s: float = 10.0) -> bool:
        """Block until ``n`` clients are connected (True) or ``timeout_s`` passed (False)."""
        deadline = time.monotonic() + timeout_s
        while self.n_clients < n and time.monotonic() < deadline:
            time.sleep(0.01)
        return self.n_clients >= n

    def send_frame(self, values: np.ndarray) -> None:
        """Send one frame's channel values to every client; clients that fail or stall are dropped."""
        line = frame_line(values, self.avatar)
        with self._lock:
            alive = []
            for conn in self._clients:
                try:
                    conn.sendall(line)
                    alive.append(conn)
                except OSError:
                    conn.close()
            self._clients = alive
        self.frames_sent += 1

    def send_motion(self, motion: Any) -> None:
        """Every frame of an `engine.mocap.Motion` (the live-output interface `PoseStreamer` uses)."""
        from engine.mocap.bvh import bvh_frame_values

        for row in bvh_frame_values(motion):
            self.send_frame(row)

    def close(self) -> None:
        self._stop.set()
        self._sock.close()
        self._thread.join(timeout=2.0)
        with self._lock:
            for conn in self._clients:
                conn.close()
            self._clients = []

    def __enter__(self) -> "BvhBroadcastServer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
