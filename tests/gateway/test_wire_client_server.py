"""Codec round-trips and a real server/client pair over 127.0.0.1: topics, requests, drop-for-display."""
from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gateway import codec, wire
from gateway.client import GatewayClient, GatewayRequestError
from gateway.server import RequestError, StreamServer


def test_codec_round_trip_keeps_arrays_and_header():
    acc = np.arange(30, dtype=np.float32).reshape(10, 3) / 7
    counters = np.arange(5, 15, dtype=np.uint32)
    body = codec.encode("samples", {"station": "st0", "sensor": 3}, {"acc_g": acc, "counter": counters})
    msg = codec.decode(body)
    assert msg.kind == "samples" and msg["station"] == "st0" and msg["sensor"] == 3
    np.testing.assert_array_equal(msg["acc_g"], acc)
    np.testing.assert_array_equal(msg["counter"], counters)
    assert msg["acc_g"].dtype == np.float32 and msg["counter"].dtype == np.uint32


@settings(max_examples=60, deadline=None)
@given(st.binary(max_size=200))
def test_codec_rejects_garbage_with_codec_error(data):
    try:
        codec.decode(data)
    except codec.CodecError:
        pass


def test_codec_truncated_payload_is_named():
    body = codec.encode("samples", {}, {"acc_g": np.zeros((4, 3), np.float32)})
    with pytest.raises(codec.CodecError, match="acc_g"):
        codec.decode(body[:-5])


def _handler(action, args, role):
    if action == "echo":
        return {"args": args}
    if action == "refuse":
        raise RequestError("not today")
    if action == "crash":
        raise ZeroDivisionError("boom")
    raise RequestError(f"unknown action {action!r}")


@pytest.fixture()
def server():
    srv = StreamServer(_handler, port=0, hello=lambda: {"gateway": "test"}, display_queue_frames=8).start()
    yield srv
    srv.close()


def test_requests_replies_and_errors(server):
    host, port = server.address
    with GatewayClient(host, port) as client:
        assert client.server_hello["gateway"] == "test"
        assert client.server_hello["protocol"] == wire.PROTOCOL_VERSION
        assert client.request("echo", take="t1") == {"args": {"take": "t1"}}
        with pytest.raises(GatewayRequestError, match="not today"):
            client.request("refuse")
        with pytest.raises(GatewayRequestError, match="ZeroDivisionError: boom"):
            client.request("crash")
        with pytest.raises(GatewayRequestError, match="unknown topics"):
            client.subscribe(["nope"])


def test_published_samples_reach_every_subscribed_client(server):
    host, port = server.address
    a, b = GatewayClient(host, port).connect(), GatewayClient(host, port).connect()
    try:
        b.subscribe(["status"])
        got: list = []
        a.add_listener("samples", got.append)
        acc = np.random.default_rng(0).normal(size=(5, 3)).astype(np.float32)
        # hello received => both sessions registered; b's subscription excludes samples
        assert server.publish("samples", {"station": "s", "sensor": 1}, {"acc_g": acc}) == 1
        assert server.publish("status", {"stations": []}) == 2
        assert a.get(2, kinds=["samples"]) is not None
        assert b.get(2, kinds=["status"]) is not None
        np.testing.assert_array_equal(got[0]["acc_g"], acc)
        # b subscribed to status only: no samples in its inbox
        assert all(m.kind != "samples" for m in b.drain())
    finally:
        a.close()
        b.close()


def test_slow_client_drops_display_frames_but_never_blocks_publisher(server):
    """A client that never reads: publishing 5000 big frames still returns quickly, and drops are counted."""
    host, port = server.address
    sock = socket.create_connection((host, port))
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    try:
        deadline = time.monotonic() + 2
        while not server.client_stats():
            assert time.monotonic() < deadline
            time.sleep(0.01)
        payload = {"acc_g": np.zeros((2000, 3), np.float32)}
        t0 = time.monotonic()
        for _ in range(5000):
            server.publish("samples", {"station": "s"}, payload)
        elapsed = time.monotonic() - t0
        stats = server.client_stats()[0]
        assert stats.dropped > 4000
        assert stats.queued <= 8 + 1
        assert elapsed < 30  # bounded: encoding only, never waiting on the socket
    finally:
        sock.close()


def test_reply_is_not_lost_behind_display_backlog(server):
    host, port = server.address
    with GatewayClient(host, port) as client:
        stop = threading.Event()

        def flood():
            while not stop.is_set():
                server.publish("samples", {"station": "s"}, {"acc_g": np.zeros((50, 3), np.float32)})

        t = threading.Thread(target=flood)
        t.start()
        try:
            for i in range(20):
                assert client.request("echo", i=i) == {"args": {"i": i}}
        finally:
            stop.set()
            t.join()


def test_client_errors_when_gateway_absent():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(OSError):
        GatewayClient("127.0.0.1", port).connect(timeout_s=1)


def test_client_that_never_reads_control_traffic_is_disconnected():
    """Reliable messages are never dropped, so a client whose reliable backlog passes the limit is cut off
    instead of growing the gateway's memory without bound."""
    srv = StreamServer(_handler, port=0, reliable_queue_limit=50).start()
    sock = socket.create_connection(srv.address)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    try:
        deadline = time.monotonic() + 2
        while not srv.client_stats():
            assert time.monotonic() < deadline
            time.sleep(0.01)
        big = {"blob": "x" * 20_000}
        deadline = time.monotonic() + 10
        while srv.client_stats():
            assert time.monotonic() < deadline, srv.client_stats()
            srv.publish("status", big)
        assert srv.publish("status", big) == 0  # gone: nothing queued for it any more
    finally:
        sock.close()
        srv.close()


@pytest.mark.parametrize("idle_deadline_s", [None, 5.0])
def test_socket_closed_by_another_thread_is_an_os_error_not_a_traceback(idle_deadline_s):
    """The server's writer thread may close a client's socket while its reader waits for the next frame; the
    reader must see an ordinary disconnect (OSError), with or without a deadline. A ValueError from select on
    fileno -1 used to escape as 'unexpected error' with a traceback in the gateway's log."""
    mine, peer = socket.socketpair()
    try:
        mine.close()
        deadline = None if idle_deadline_s is None else time.monotonic() + idle_deadline_s
        with pytest.raises(OSError):
            wire.recv_message(mine, frame_timeout_s=1.0, idle_deadline=deadline)
    finally:
        peer.close()
