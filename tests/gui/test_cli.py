"""`courtside console` against a real gateway (in-process, emulated station on a pty), and its error paths."""
from __future__ import annotations

import socket

from firmware_protocol.emulator.motion import StillSource
from gui.cli import console_main, demo_main


def test_console_connects_runs_and_saves_screenshots(live_gateway, qapp, tmp_path, monkeypatch):
    monkeypatch.setenv("COURTSIDE_CACHE_DIR", str(tmp_path / "cache"))
    gateway, _ = live_gateway(StillSource(6), 6)
    host, port = gateway.address
    code = console_main(["--connect", f"{host}:{port}", "--duration", "3", "--screenshots", str(tmp_path / "shots")])
    assert code == 0
    assert (tmp_path / "shots" / "main.png").stat().st_size > 10_000
    assert (tmp_path / "shots" / "devices.png").is_file()


def test_console_reports_unreachable_gateway(qapp, capsys):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # bound but not listening: connection refused
        assert console_main(["--connect", f"127.0.0.1:{port}"]) == 2
    assert f"cannot connect to gateway 127.0.0.1:{port}" in capsys.readouterr().err


def test_demo_screenshots_need_a_duration(capsys):
    assert demo_main(["--screenshots", "x"]) == 2
    assert "--screenshots needs --duration" in capsys.readouterr().err


def test_console_plays_back_a_take_and_rejects_a_bad_one(live_gateway, qapp, tmp_path, monkeypatch, capsys):
    import time

    from gateway.client import GatewayClient

    monkeypatch.setenv("COURTSIDE_CACHE_DIR", str(tmp_path / "cache"))
    gateway, _ = live_gateway(StillSource(6), 6)
    with GatewayClient(*gateway.address).connect() as client:
        client.start_recording("cli-take")
        time.sleep(1.5)
        take = client.stop_recording()["files"][0]
    assert console_main(["--playback", take, "--duration", "2", "--screenshots", str(tmp_path / "shots")]) == 0
    assert (tmp_path / "shots" / "main.png").is_file()
    bogus = tmp_path / "bogus.csrec"
    bogus.write_bytes(b"not a take")
    assert console_main(["--playback", str(bogus)]) == 2
    err = capsys.readouterr().err
    assert "cannot play back" in err and "bogus.csrec" in err
