"""Every field of every client message type-checked before use (issue 22, item 2), against a real gateway on
loopback: a hypothesis fuzz over the whole request schema (auth, subscribe, request with every action and its
arguments, ids, unknown kinds) from unauthenticated, viewer and operator connections; the issue's exact cases;
and an impostor gateway answering with a non-ASCII proof, through the client and through the console process."""
from __future__ import annotations

import logging
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gateway import auth, wire
from gateway.client import GatewayClient
from gateway.daemon import Gateway

HOST = "127.0.0.6"
ROOT = Path(__file__).resolve().parents[2]

json_scalars = st.one_of(st.none(), st.booleans(), st.integers(-2**70, 2**70),
                         st.floats(allow_nan=False, allow_infinity=False), st.text(max_size=70))
json_values = st.recursive(json_scalars, lambda inner: st.lists(inner, max_size=4)
                           | st.dictionaries(st.text(max_size=10), inner, max_size=4), max_leaves=12)
hex64 = st.binary(min_size=32, max_size=32).map(bytes.hex)
# field values: well-typed ones (so deeper checks are reached) mixed with anything JSON can carry
odd_text = st.text(alphabet=st.characters(min_codepoint=0x80, max_codepoint=0x2FFF), min_size=1, max_size=64)


def field(good: st.SearchStrategy) -> st.SearchStrategy:
    return st.one_of(good, json_values, odd_text)


ACTION_ARGS = {
    "ping": st.just({}), "list_stations": st.just({}), "status": st.just({}), "stop_recording": st.just({}),
    "start_recording": st.fixed_dictionaries({"take": field(st.from_regex(r"[a-z][a-z0-9-]{0,12}", fullmatch=True))}),
    "station_command": st.fixed_dictionaries({
        "station": field(st.sampled_from(["st1", "emu"])), "command": field(st.sampled_from(["identify", "set_rate"])),
        "args": field(st.dictionaries(st.sampled_from(["sensor", "rate_hz"]), json_values, max_size=2))}),
    "calibration": st.fixed_dictionaries({"action": field(st.sampled_from(["state", "assign", "start"])),
                                          "args": field(st.dictionaries(st.text(max_size=8), json_values, max_size=3))}),
}
ids = field(st.integers(0, 2**31))
requests = st.sampled_from(sorted(ACTION_ARGS)).flatmap(lambda action: st.fixed_dictionaries({
    "id": ids, "action": field(st.just(action)), "args": field(ACTION_ARGS[action])}))
messages = st.one_of(
    st.tuples(st.just(wire.REQUEST), requests),
    st.tuples(st.just(wire.AUTH), st.fixed_dictionaries({"id": ids, "nonce": field(hex64), "proof": field(hex64)})),
    st.tuples(st.just(wire.SUBSCRIBE), st.fixed_dictionaries(
        {"id": ids, "topics": field(st.lists(st.sampled_from(wire.TOPICS), max_size=3))})),
    st.tuples(st.text(min_size=1, max_size=12), st.dictionaries(st.text(max_size=8), json_values, max_size=3)),
)


def _secret(tmp_path: Path, name: str) -> Path:
    path = tmp_path / name
    auth.write_secret_file(path)
    return path


def _recv(sock: socket.socket, timeout_s: float = 5.0):
    return wire.recv_message(sock, idle_deadline=time.monotonic() + timeout_s, frame_timeout_s=timeout_s)


def _login(sock: socket.socket, secret: bytes) -> None:
    hello = _recv(sock)
    server_nonce, client_nonce = bytes.fromhex(hello["auth"]["challenge"]), os.urandom(32)
    sock.sendall(wire.pack(wire.AUTH, {"id": 0, "nonce": client_nonce.hex(),
                                       "proof": auth.proof(secret, "client", server_nonce, client_nonce)}))
    assert _recv(sock)["ok"]


def _answer(sock: socket.socket) -> str:
    """'reply' (any reply) or 'closed' (clean close); anything else fails the test."""
    try:
        while True:
            msg = _recv(sock)
            if msg is None:
                return "closed"
            if msg.kind == wire.REPLY:
                return "reply"
    except ConnectionResetError:
        return "closed"


@pytest.fixture()
def traced_errors(caplog):
    """Thread deaths (`threading.excepthook`) and log records carrying a traceback, from the gateway."""
    died: list[str] = []
    old_hook = threading.excepthook
    threading.excepthook = lambda args: died.append(f"{args.thread.name}: {args.exc_type.__name__}: {args.exc_value}")
    caplog.set_level(logging.INFO, logger="gateway")
    try:
        yield lambda: died + [f"{r.name}: {r.getMessage()}" for r in caplog.records if r.exc_info]
    finally:
        threading.excepthook = old_hook


def test_fuzz_the_whole_request_schema_against_a_real_server(tmp_path, traced_errors):
    op_file, viewer_file = _secret(tmp_path, "op"), _secret(tmp_path, "viewer")
    secrets = auth.Secrets.from_files(op_file, viewer_file)
    role_secrets = {"none": None, "viewer": secrets.viewer, "operator": secrets.operator}
    gw = Gateway([], listen=(HOST, 0), record_dir=tmp_path / "rec", secrets=secrets, status_interval_s=30.0,
                 handshake_timeout_s=2.0, max_clients=8).start()
    outcomes: dict[str, int] = {}
    try:
        @settings(max_examples=250, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)
        @given(role=st.sampled_from(sorted(role_secrets)), message=messages)
        def one(role, message):
            kind, header = message
            with socket.create_connection(gw.address, timeout=5) as sock:
                if role_secrets[role] is None:
                    assert _recv(sock).kind == wire.SERVER_HELLO
                else:
                    _login(sock, role_secrets[role])
                sock.sendall(wire.pack(kind, header))
                answer = _answer(sock)
            outcomes[f"{role}-{answer}"] = outcomes.get(f"{role}-{answer}", 0) + 1

        one()
        assert traced_errors() == []
        # the server still serves, to every role
        with GatewayClient(*gw.address, secret=secrets.operator) as operator:
            assert operator.request("ping")["t_host_s"] > 0 and operator.role == auth.OPERATOR
        with GatewayClient(*gw.address, secret=secrets.viewer) as viewer:
            assert viewer.status()["clients"] == []
    finally:
        gw.stop()
    assert outcomes.get("operator-reply", 0) > 20 and outcomes.get("viewer-reply", 0) > 20, outcomes
    assert outcomes.get("operator-closed", 0) == 0 and outcomes.get("viewer-closed", 0) == 0, outcomes


@pytest.mark.parametrize("header, error", [
    ({"nonce": "ab" * 32, "proof": "é" * 64}, "'proof' must be 64 lowercase hex"),  # compare_digest TypeError
    ({"nonce": "ab" * 32, "proof": ["00"] * 32}, "'proof' must be 64 lowercase hex"),
    ({"nonce": "€" * 64, "proof": "00" * 32}, "'nonce' must be 64 lowercase hex"),
    ({"nonce": {"a": 1}, "proof": "00" * 32}, "'nonce' must be 64 lowercase hex"),
])
def test_odd_authentication_fields_get_one_reply_and_a_close(tmp_path, traced_errors, header, error):
    gw = Gateway([], listen=(HOST, 0), record_dir=tmp_path / "rec", status_interval_s=30.0,
                 secrets=auth.Secrets.from_files(_secret(tmp_path, "op"), None)).start()
    try:
        with socket.create_connection(gw.address, timeout=5) as sock:
            assert _recv(sock).kind == wire.SERVER_HELLO
            sock.sendall(wire.pack(wire.AUTH, {"id": 3, **header}))
            reply = _recv(sock)
            assert reply["id"] == 3 and not reply["ok"] and error in reply["error"], reply.header
            assert _answer(sock) == "closed"
    finally:
        gw.stop()
    assert traced_errors() == []


@pytest.mark.parametrize("request_header, error", [
    ({"action": "calibration", "args": {"action": ["state"]}}, "calibration: 'action' must be a string, got a list"),
    ({"action": "calibration", "args": {"action": {"a": 1}}}, "'action' must be a string, got an object"),
    ({"action": ["ping"], "args": {}}, "string 'action'"),
    ({"action": "station_command", "args": {"station": "st1", "command": "identify", "args": {"sensor": [1]}}},
     "argument 'sensor' must be a number"),
    ({"action": "start_recording", "args": {"take": 7}}, "'take' must be a string, got an integer"),
    ({"id": {"x": 1}, "action": "ping", "args": {}}, "'id' must be an integer or a string"),
])
def test_odd_request_fields_are_refused_by_name(tmp_path, traced_errors, request_header, error):
    gw = Gateway([], listen=(HOST, 0), record_dir=tmp_path / "rec", status_interval_s=30.0).start()
    try:
        with socket.create_connection(gw.address, timeout=5) as sock:
            assert _recv(sock).kind == wire.SERVER_HELLO
            sock.sendall(wire.pack(wire.REQUEST, {"id": 9, **request_header}))
            reply = _recv(sock)
            assert not reply["ok"] and error in reply["error"], reply.header
            sock.sendall(wire.pack(wire.SUBSCRIBE, {"id": 10, "topics": [["samples"]]}))  # was: unhashable
            reply = _recv(sock)
            assert reply["id"] == 10 and "'topics' must be a list of strings" in reply["error"]
            sock.sendall(wire.pack(wire.REQUEST, {"id": 11, "action": "ping", "args": {}}))
            assert _recv(sock)["ok"]  # the same connection still serves
    finally:
        gw.stop()
    assert traced_errors() == []


def impostor_gateway(proof: str) -> tuple[socket.socket, threading.Thread]:
    """A server without the secret that greets with a challenge and 'accepts' with ``proof``."""
    listener = socket.create_server((HOST, 0))

    def serve():
        conn, _ = listener.accept()
        with conn:
            conn.sendall(wire.pack("hello", {"protocol": 2, "auth": {"challenge": os.urandom(32).hex()}}))
            request = wire.recv_message(conn)
            conn.sendall(wire.pack("reply", {"id": request["id"], "ok": True,
                                             "result": {"role": "operator", "proof": proof}}))
            time.sleep(1.0)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    return listener, thread


def test_an_impostor_with_a_non_ascii_proof_is_an_authentication_error(tmp_path):
    listener, thread = impostor_gateway("é" * 64)
    try:
        with pytest.raises(auth.AuthenticationError, match="could not prove it holds the secret"):
            GatewayClient(*listener.getsockname()[:2], secret=auth.read_secret_file(_secret(tmp_path, "s"))).connect()
    finally:
        thread.join(5)
        listener.close()


def test_the_console_exits_2_with_one_line_on_animpostor_gateway(tmp_path):
    listener, thread = impostor_gateway("ü" * 64)
    host, port = listener.getsockname()[:2]
    try:
        done = subprocess.run([sys.executable, "-m", "gateway.cli", "console", "--connect", f"{host}:{port}",
                               "--secret-file", str(_secret(tmp_path, "s"))], capture_output=True, text=True,
                              timeout=120, cwd=ROOT, env={**os.environ, "QT_QPA_PLATFORM": "offscreen"})
    finally:
        thread.join(5)
        listener.close()
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert "could not prove it holds the secret" in lines[0] and "Traceback" not in done.stderr
