"""Authentication, roles and server limits over real sockets on non-default loopback addresses (issues 12, 13):
challenge-response with operator/viewer secrets, the server refusing every state-changing request a viewer or
an unauthenticated connection makes, hidden client addresses, handshake and frame timeouts, bounded frames
read incrementally, undecodable frames answered, connection cap, strict take names."""
from __future__ import annotations

import json
import logging
import os
import shutil
import socket
import struct
import subprocess
import time
import tracemalloc

import pytest

from engine.errors import MalformedFileError
from gateway import auth, codec, server, wire
from gateway.client import GatewayClient, GatewayRequestError
from gateway.daemon import Gateway

HOST = "127.0.0.2"  # a loopback address other than the default


def secret_file(tmp_path, name: str, mode: int = 0o600):
    path = tmp_path / name
    auth.write_secret_file(path)
    os.chmod(path, mode)
    return path


@pytest.fixture()
def secured(tmp_path):
    """An authenticated gateway on 127.0.0.2 with operator and viewer secrets."""
    op, view = secret_file(tmp_path, "operator"), secret_file(tmp_path, "viewer")
    secrets = auth.Secrets.from_files(op, view)
    gw = Gateway([], listen=(HOST, 0), record_dir=tmp_path / "rec", secrets=secrets, status_interval_s=0.2,
                 handshake_timeout_s=1.0, max_clients=4).start()
    try:
        yield gw, auth.read_secret_file(op), auth.read_secret_file(view)
    finally:
        gw.stop()


def raw_connect(address) -> socket.socket:
    sock = socket.create_connection(address, timeout=5)
    return sock


def recv(sock: socket.socket, timeout_s: float = 5.0):
    return wire.recv_message(sock, idle_deadline=time.monotonic() + timeout_s, frame_timeout_s=timeout_s)


def closed_within(sock: socket.socket, timeout_s: float) -> bool:
    """True if the server closes ``sock`` within ``timeout_s`` (frames before the EOF are skipped)."""
    sock.settimeout(timeout_s)
    end = time.monotonic() + timeout_s
    try:
        while time.monotonic() < end:
            if not sock.recv(65536):
                return True
    except (socket.timeout, ConnectionResetError):
        return False
    return False


def test_operator_viewer_and_unauthenticated_clients(secured, tmp_path):
    gw, operator_secret, viewer_secret = secured
    with GatewayClient(*gw.address, secret=operator_secret) as op:
        assert op.role == auth.OPERATOR and "stations" in op.server_hello
        state = op.start_recording("t1")
        assert state["active"] and state["take"] == "t1"
        with GatewayClient(*gw.address, secret=viewer_secret) as viewer:
            assert viewer.role == auth.VIEWER
            assert viewer.request("ping")["t_host_s"] > 0 and isinstance(viewer.list_stations(), list)
            # every state-changing request is refused by the server, naming the role it needs
            with pytest.raises(GatewayRequestError, match="'stop_recording' needs the operator role"):
                viewer.stop_recording()
            with pytest.raises(GatewayRequestError, match="needs the operator role"):
                viewer.start_recording("t2")
            with pytest.raises(GatewayRequestError, match="needs the operator role"):
                viewer.station_command("st1", "stop")
            with pytest.raises(GatewayRequestError, match="needs the operator role"):
                viewer.calibration("assign", sensor="st1/0", segment="chest")
            assert gw.recorder.active and gw.recorder.state()["take"] == "t1"
            # viewers see how many clients there are, not their addresses (request and periodic status)
            status = viewer.status()
            assert status["n_clients"] == 2 and status["clients"] == []
            assert all(c["address"].startswith("127.0.0.2") or c["address"].startswith("127.")
                       for c in op.status()["clients"]) and len(op.status()["clients"]) == 2
            periodic = viewer.get(timeout_s=3.0, kinds=["status"])
            assert periodic is not None and periodic["clients"] == [] and periodic["n_clients"] == 2
            periodic = op.get(timeout_s=3.0, kinds=["status"])
            assert len(periodic["clients"]) == 2
        assert op.stop_recording()["take"] == "t1"

    # no secret: refused before anything is disclosed; a wrong secret: refused
    with pytest.raises(auth.AuthenticationError, match="requires authentication"):
        GatewayClient(*gw.address).connect()
    with pytest.raises(auth.AuthenticationError, match="authentication failed"):
        GatewayClient(*gw.address, secret=b"not-the-secret-0123456789").connect()


def test_unauthenticated_connection_gets_nothing_and_is_refused_control(secured):
    gw, _, _ = secured
    sock = raw_connect(gw.address)
    try:
        hello = recv(sock)
        assert hello.kind == "hello" and "challenge" in hello["auth"]
        assert "stations" not in hello.header  # nothing about the court before authentication
        sock.sendall(wire.pack(wire.REQUEST, {"id": 1, "action": "stop_recording", "args": {}}))
        reply = recv(sock)
        assert reply.kind == "reply" and not reply["ok"] and "authenticate first" in reply["error"]
        assert closed_within(sock, 3.0)
    finally:
        sock.close()
    assert not gw.recorder.active


def test_handshake_that_never_completes_times_out(secured):
    gw, _, _ = secured
    sock = raw_connect(gw.address)
    try:
        assert recv(sock).kind == "hello"
        started = time.monotonic()
        assert closed_within(sock, 5.0)  # handshake_timeout_s = 1.0
        assert time.monotonic() - started < 4.0
    finally:
        sock.close()


def test_client_detects_an_impostor_gateway(tmp_path):
    """A server that does not hold the secret cannot produce the server proof."""
    from .test_request_fuzz import impostor_gateway

    listener, thread = impostor_gateway("00" * 32)
    secret = auth.read_secret_file(secret_file(tmp_path, "s"))
    with pytest.raises(auth.AuthenticationError, match="could not prove"):
        GatewayClient(*listener.getsockname()[:2], secret=secret).connect()
    thread.join(5)
    listener.close()


def test_secret_files_readable_by_others_or_too_short_are_refused(tmp_path):
    loose = secret_file(tmp_path, "loose", mode=0o644)
    with pytest.raises(MalformedFileError, match="readable by others"):
        auth.read_secret_file(loose)
    short = tmp_path / "short"
    short.write_text("abc\n")
    os.chmod(short, 0o600)
    with pytest.raises(MalformedFileError, match="at least 16"):
        auth.read_secret_file(short)
    assert auth.client_secret(environ={auth.SECRET_FILE_ENV: str(secret_file(tmp_path, "env"))})
    assert auth.client_secret(environ={}) is None
    with pytest.raises(FileExistsError):
        auth.write_secret_file(tmp_path / "env")  # never overwrites


@pytest.fixture()
def open_gateway(tmp_path):
    """Loopback, no secret: every client is an operator (documented), but the server limits still hold."""
    gw = Gateway([], listen=("127.0.0.3", 0), record_dir=tmp_path / "rec", handshake_timeout_s=1.0,
                 max_clients=3).start()
    try:
        yield gw
    finally:
        gw.stop()


def test_oversized_frame_prefix_is_refused_without_allocating(open_gateway):
    gw = open_gateway
    tracemalloc.start()
    try:
        # a prefix within the limit but only 10 body bytes: memory follows the bytes that arrive
        sock = raw_connect(gw.address)
        assert recv(sock).kind == "hello"
        tracemalloc.reset_peak()
        before = tracemalloc.get_traced_memory()[0]
        sock.sendall(struct.pack(">I", wire.MAX_REQUEST_BYTES) + b"x" * 10)
        time.sleep(0.3)
        assert tracemalloc.get_traced_memory()[1] - before < wire.MAX_REQUEST_BYTES // 4
        assert closed_within(sock, 5.0)  # and the unfinished frame times out
        sock.close()
        # a prefix over the limit: closed at once
        sock = raw_connect(gw.address)
        assert recv(sock).kind == "hello"
        tracemalloc.reset_peak()
        before = tracemalloc.get_traced_memory()[0]
        sock.sendall(struct.pack(">I", 64 << 20))
        assert closed_within(sock, 2.0)
        assert tracemalloc.get_traced_memory()[1] - before < 1 << 20
        sock.close()
    finally:
        tracemalloc.stop()
    with GatewayClient(*gw.address) as client:  # the server is fine
        assert client.request("ping")


def _frame(header_json: bytes) -> bytes:
    body = struct.pack(">I", len(header_json)) + header_json
    return struct.pack(">I", len(body)) + body


def test_deep_json_and_absurd_shapes_get_an_error_reply_and_one_log_line(open_gateway, caplog):
    gw = open_gateway
    sock = raw_connect(gw.address)
    try:
        assert recv(sock).kind == "hello"
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="gateway.server"):
            deep = b'{"kind":"request","x":' + b"[" * 200_000 + b"]" * 200_000 + b"}"
            sock.sendall(_frame(deep))
            reply = recv(sock)
            assert reply.kind == "reply" and not reply["ok"] and "nested too deeply" in reply["error"]
            shape = json.dumps({"kind": "request", "arrays": [{"name": "a", "dtype": "<f8",
                                                               "shape": [2**32, 2**32]}]}).encode()
            sock.sendall(_frame(shape))
            reply = recv(sock)
            assert not reply["ok"] and "'a' needs" in reply["error"]
            sock.sendall(wire.pack(wire.REQUEST, {"id": 7, "action": "ping", "args": {}}))
            reply = recv(sock)
            assert reply["id"] == 7 and reply["ok"]  # the same connection still works
        server_lines = [r for r in caplog.records if r.name == "gateway.server"]
        assert len(server_lines) == 2 and not any(r.exc_info for r in server_lines)
        # a flood of garbage frames is cut off instead of flooding the log
        for _ in range(server.MAX_BAD_FRAMES + 5):
            try:
                sock.sendall(_frame(b"not json"))
            except (BrokenPipeError, ConnectionResetError):
                break  # the server already cut the connection off (what is tested), before the last frames
        assert closed_within(sock, 5.0)
    finally:
        sock.close()


def test_connection_cap(open_gateway):
    gw = open_gateway
    clients = [GatewayClient(*gw.address).connect() for _ in range(3)]
    try:
        with pytest.raises(ConnectionError, match="busy"):
            GatewayClient(*gw.address).connect()
        assert gw.server.refused_connections == 1
    finally:
        for client in clients:
            client.close()
    deadline = time.monotonic() + 5
    while len(gw.server.client_stats()) and time.monotonic() < deadline:
        time.sleep(0.05)
    with GatewayClient(*gw.address) as again:  # room again once they left
        assert again.request("ping")


@pytest.mark.parametrize("take", ["..", ".", "../take", "a/b", "take\n", "x" * 101, "", ".hidden", "-rf", "tab\there"])
def test_take_names_are_validated_strictly(open_gateway, tmp_path, take):
    gw = open_gateway
    with GatewayClient(*gw.address) as client:
        with pytest.raises(GatewayRequestError, match="take name"):
            client.start_recording(take)
    assert not gw.recorder.active
    assert not (tmp_path / "take.csrec").exists() and not (tmp_path / "rec" / "take.csrec").exists()
    assert not list(tmp_path.glob("*/take.csrec")) and not list((tmp_path).glob("take*"))


def test_codec_refuses_negative_shapes():
    header = json.dumps({"kind": "x", "arrays": [{"name": "a", "dtype": "<f4", "shape": [-1]}]}).encode()
    with pytest.raises(codec.CodecError, match="invalid shape"):
        codec.decode(struct.pack(">I", len(header)) + header + b"\0" * 8)


def make_certificate(tmp_path):
    """A self-signed certificate for 127.0.0.2 via the openssl command (no Python crypto dependency)."""
    if shutil.which("openssl") is None:
        pytest.skip("openssl command not installed")
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1",
                    "-nodes", "-days", "2", "-subj", "/CN=courtside-gateway", "-keyout", str(key), "-out", str(cert)],
                   check=True, capture_output=True, timeout=60)
    return cert, key


def test_tls_with_authentication_full_duplex(tmp_path):
    cert, key = make_certificate(tmp_path)
    operator = auth.read_secret_file(secret_file(tmp_path, "operator"))
    gw = Gateway([], listen=(HOST, 0), record_dir=tmp_path / "rec", secrets=auth.Secrets(operator),
                 tls=auth.server_tls_context(cert, key), status_interval_s=0.1, handshake_timeout_s=2.0).start()
    try:
        with GatewayClient(*gw.address, secret=operator, tls=auth.client_tls_context(cert)) as client:
            assert client.role == auth.OPERATOR
            # replies and the periodic stream interleave on one TLS connection (reader and writer threads)
            for _ in range(30):
                assert client.request("ping")["t_host_s"] > 0
            assert client.get(timeout_s=3.0, kinds=["status"]) is not None
            assert client.start_recording("tls-take")["active"]
            assert client.stop_recording()["take"] == "tls-take"
        # a client speaking plain TCP to the TLS port gets nothing and is dropped
        sock = raw_connect(gw.address)
        try:
            sock.sendall(wire.pack(wire.REQUEST, {"id": 1, "action": "ping", "args": {}}))
            assert closed_within(sock, 5.0)
        finally:
            sock.close()
        # a plain client (a console without --tls-ca) is told what to do, not just that no hello came
        with pytest.raises(ConnectionError, match="a TLS gateway waits for a TLS handshake.*--tls-ca"):
            GatewayClient(*gw.address, secret=operator).connect(timeout_s=0.5)
        # a client that does not trust the certificate refuses the gateway
        (tmp_path / "other").mkdir()
        other_cert, _ = make_certificate(tmp_path / "other")
        with pytest.raises(ConnectionError, match="TLS handshake failed"):
            GatewayClient(*gw.address, secret=operator, tls=auth.client_tls_context(other_cert)).connect()
    finally:
        gw.stop()


def test_unanswered_handshakes_cannot_hold_every_slot(tmp_path):
    """Connections that never authenticate are bounded separately (max_pending): the oldest makes room, so a
    real client still gets in; authenticated clients are capped by max_clients."""
    secret = auth.read_secret_file(secret_file(tmp_path, "operator"))
    gw = Gateway([], listen=(HOST, 0), record_dir=tmp_path / "rec", secrets=auth.Secrets(secret),
                 handshake_timeout_s=30.0, max_clients=1)
    gw.server.max_pending = 2
    gw.start()
    silent = []
    try:
        for _ in range(4):  # a slow flood of connections that never answer
            sock = raw_connect(gw.address)
            assert recv(sock).kind == "hello"
            silent.append(sock)
        with GatewayClient(*gw.address, secret=secret) as first:
            assert first.role == auth.OPERATOR
            assert sum(closed_within(s, 0.5) for s in silent) >= 3  # the oldest ones were dropped
            with pytest.raises(ConnectionError, match="busy"):
                GatewayClient(*gw.address, secret=secret).connect()  # max_clients=1 authenticated
            assert first.request("ping")
    finally:
        for sock in silent:
            sock.close()
        gw.stop()


def test_a_client_object_reconnects_from_scratch(secured):
    """The console reconnects with the same GatewayClient: the old hello must not satisfy the new connect."""
    gw, operator_secret, _ = secured
    client = GatewayClient(*gw.address, secret=operator_secret)
    client.connect()
    assert client.role == auth.OPERATOR
    client.close()
    client.connect()
    assert client.role == auth.OPERATOR and client.request("ping")
    client.close()
    wrong = GatewayClient(*gw.address, secret=operator_secret)
    wrong.connect()
    wrong.close()
    wrong._secret = b"not-the-secret-0123456789"
    with pytest.raises(auth.AuthenticationError):
        wrong.connect()
    assert wrong.role is None
