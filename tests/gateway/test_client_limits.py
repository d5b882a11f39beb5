"""Client limits with separate clients on loopback (issue 22, items 3 and 4): viewers filling the gateway cannot
lock the operator out, and clients that ask without reading cannot grow the gateway: every queue is bounded in
bytes and all of them share one budget."""
from __future__ import annotations

import os
import socket

from gateway import auth, wire
from gateway.client import GatewayClient
from gateway.daemon import Gateway
from gateway.server import StreamServer

from .test_station_reader import wait_for

HOST = "127.0.0.7"


def _secret(tmp_path, name):
    path = tmp_path / name
    auth.write_secret_file(path)
    return auth.read_secret_file(path), path


def test_viewers_filling_the_gateway_cannot_lock_the_operator_out(tmp_path):
    operator_secret, op_file = _secret(tmp_path, "op")
    viewer_secret, viewer_file = _secret(tmp_path, "viewer")
    gw = Gateway([], listen=(HOST, 0), record_dir=tmp_path / "rec", status_interval_s=30.0, max_clients=3,
                 secrets=auth.Secrets.from_files(op_file, viewer_file)).start()
    viewers = [GatewayClient(*gw.address, secret=viewer_secret).connect() for _ in range(3)]
    try:
        assert all(v.role == auth.VIEWER for v in viewers)
        # a fourth viewer is refused: viewers do not evict each other
        try:
            GatewayClient(*gw.address, secret=viewer_secret).connect()
            raise AssertionError("a viewer beyond the limit was accepted")
        except ConnectionError as exc:
            assert "busy" in str(exc)
        # the operator gets in: the viewer that came first is told why and disconnected
        with GatewayClient(*gw.address, secret=operator_secret) as operator:
            assert operator.role == auth.OPERATOR and operator.start_recording("t1")["active"]
            assert wait_for(lambda: not viewers[0].connected, 10.0)
            assert viewers[1].connected and viewers[2].connected
            assert viewers[1].request("ping") and gw.server.authenticated_clients() == 3
            # a second operator finds the next viewer's slot
            with GatewayClient(*gw.address, secret=operator_secret) as second:
                assert second.role == auth.OPERATOR and wait_for(lambda: not viewers[1].connected, 10.0)
            operator.stop_recording()
        event = next((m for m in viewers[0].drain() if m.kind == "event"), None)
        assert event is not None and "operator needs this viewer's slot" in event["message"]
    finally:
        for viewer in viewers:
            viewer.close()
        gw.stop()


def _ask_without_reading(address, n_requests: int) -> tuple[socket.socket, int]:
    """A client that sends ``status`` requests and never reads a reply (issue 22's memory probe); returns the
    socket and how many requests it got out before the gateway stopped taking them."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # before connecting: a small receive window
    sock.settimeout(5)
    sock.connect(address)
    request = wire.pack(wire.REQUEST, {"id": 1, "action": "status", "args": {}})
    sent = 0
    try:
        for sent in range(1, n_requests + 1):
            sock.sendall(request)
    except OSError:  # the gateway gave up on us (or stopped reading us): that is the point
        pass
    return sock, sent


def test_clients_that_ask_without_reading_stay_within_the_byte_budget(tmp_path):
    """Status replies are reliable (never dropped). Four clients asking thousands of times without reading used to
    queue up to 10 000 replies each (139 MB in 13 s); now each client's reliable queue is cut at its byte limit
    and the sum over clients never exceeds the budget, while a client that reads is served throughout."""
    limit, budget = 256 << 10, 768 << 10
    # a status reply with many stations is large: give the gateway some (unconnected) ports to report
    gw = Gateway([f"/nonexistent/tty{i}" for i in range(12)], listen=(HOST, 0), record_dir=tmp_path / "rec",
                 status_interval_s=30.0, max_clients=8,
                 server_options={"reliable_queue_bytes": limit, "queue_budget_bytes": budget}).start()
    try:
        reply_bytes = len(wire.pack(wire.REPLY, {"id": 1, "ok": True, "result": gw.handle_request("status", {})}))
        sockets = []
        with GatewayClient(*gw.address) as reader:
            for _ in range(4):
                sock, sent = _ask_without_reading(gw.address, 3000)  # replies worth ~80x the client's limit
                sockets.append(sock)
                assert reader.request("ping")
            assert reader.status()["n_clients"] >= 1 and reader.connected
        # the high-water mark, not a sample: a non-reader's backlog may be cut within microseconds of forming
        assert 0 < gw.server.peak_queued_bytes <= budget, gw.server.peak_queued_bytes
        # the non-readers were cut off (the kernel's buffers held only a few replies each)
        assert wait_for(lambda: len(gw.server.client_stats()) == 0, 10.0), gw.server.client_stats()
        assert gw.server.queued_bytes == 0
        for sock in sockets:
            sock.close()
    finally:
        gw.stop()
    assert reply_bytes * 10_000 > 100 * limit  # the old 10 000-frame bound allowed 100x this byte limit


def test_display_frames_of_a_stalled_client_stay_within_its_byte_limit():
    server = StreamServer(lambda a, b, r: None, host=HOST, port=0, display_queue_frames=100_000,
                          display_queue_bytes=256 << 10, queue_budget_bytes=1 << 20).start()
    try:
        sock = socket.create_connection(server.address, timeout=5)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        assert wait_for(lambda: server.authenticated_clients() == 1, 10.0)
        payload = {"x": os.urandom(4000).hex()}
        for _ in range(2000):  # 16 MB of display frames at a client that never reads
            server.publish("samples", payload)
        stats = server.client_stats()[0]
        # the kernel's socket buffers take a few MB; the rest is dropped oldest-first, never queued past the limit
        assert stats.queued_bytes <= 256 << 10 and stats.dropped > 500, stats
        # every frame accounted for (+1 the hello; one frame may be inside a blocked sendall, popped but not sent)
        assert 2000 <= stats.sent + stats.dropped + stats.queued <= 2000 + 1, stats
        assert server.queued_bytes <= (1 << 20) // 2  # display frames may use half the budget
        sock.close()
    finally:
        server.close()
