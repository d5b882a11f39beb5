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


def test_console_closes_after_its_screenshots_even_when_the_close_falls_inside_the_capture(live_gateway, tmp_path):
    """--duration 0.5 --screenshots: the capture starts at once and pumps the event loop for 0.8 s, so the close
    used to fire inside that nested loop, which swallowed the quit: the console never exited (found as a hung
    suite run on the loaded machine). A subprocess, so the old behaviour shows as a timeout, not a hung test."""
    import os
    import subprocess
    import sys

    gateway, _ = live_gateway(StillSource(6), 6)
    host, port = gateway.address
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", COURTSIDE_CACHE_DIR=str(tmp_path / "cache"))
    proc = subprocess.run([sys.executable, "-m", "gateway.cli", "console", "--connect", f"{host}:{port}",
                           "--duration", "0.5", "--screenshots", str(tmp_path / "shots")],
                          capture_output=True, text=True, timeout=60, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
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
        # generous reply deadlines (the default is 5 s): a loaded machine only makes the gateway slower to answer
        client.request("start_recording", take="cli-take", timeout_s=60.0)
        time.sleep(1.5)
        take = client.request("stop_recording", timeout_s=60.0)["files"][0]
    assert console_main(["--playback", take, "--duration", "2", "--screenshots", str(tmp_path / "shots")]) == 0
    assert (tmp_path / "shots" / "main.png").is_file()
    bogus = tmp_path / "bogus.csrec"
    bogus.write_bytes(b"not a take")
    assert console_main(["--playback", str(bogus)]) == 2
    err = capsys.readouterr().err
    assert "cannot play back" in err and "bogus.csrec" in err


def test_console_reads_each_segment_from_the_sensor_the_calibration_record_assigned(live_gateway, qapp, tmp_path,
                                                                                     monkeypatch, capsys):
    import json

    import numpy as np

    import gui.engine_link
    from engine.mocap import SEED000_SENSORS, load_clip, sample_clips, standard_placements

    monkeypatch.setenv("COURTSIDE_CACHE_DIR", str(tmp_path / "cache"))
    skeleton = load_clip(next(p for n, p in sample_clips().items() if n.startswith("16_"))).skeleton  # the console's
    nominal = {p.name: p.rotation for p in standard_placements(skeleton, tuple(SEED000_SENSORS))}

    def record(ids):
        doc = {"schema": "courtside.sensor_calibration", "schema_version": 1, "sensors": {
            sid: {"segment": seg, "rotation": np.asarray(nominal[seg]).tolist(), "gravity_sensor_g": [0, 1, 0],
                  "norm_error_g": 0.0, "correction_deg": 0.0, "passed": True} for seg, sid in ids.items()}}
        path = tmp_path / "take.calibration.json"
        path.write_text(json.dumps(doc))
        return str(path)

    worn = []
    setup = gui.engine_link.synthesis_setup
    monkeypatch.setattr(gui.engine_link, "synthesis_setup", lambda spec, sensors, lag: worn.append(sensors) or
                        setup(spec, sensors, lag))
    gateway, _ = live_gateway(StillSource(6), 6)
    host, port = gateway.address
    reversed_ids = {seg: f"st1/{5 - i}" for i, seg in enumerate(SEED000_SENSORS)}  # worn in the opposite order
    assert console_main(["--connect", f"{host}:{port}", "--duration", "1", "--calibration",
                         record(reversed_ids)]) == 0
    assert worn == [[("st1", 5 - i) for i in range(6)]]
    bad = dict(reversed_ids, chest="chest-sensor")
    assert console_main(["--connect", f"{host}:{port}", "--calibration", record(bad)]) == 2
    assert "sensor id 'chest-sensor' on 'chest'" in capsys.readouterr().err


def test_scripted_record_of_an_existing_take_is_refused_with_exit_1(live_gateway, qapp, tmp_path, monkeypatch,
                                                                   capsys):
    """Unattended capture must not report success when the gateway refuses the take (here: it exists)."""
    import time

    from gateway.client import GatewayClient

    monkeypatch.setenv("COURTSIDE_CACHE_DIR", str(tmp_path / "cache"))
    gateway, _ = live_gateway(StillSource(6), 6)
    with GatewayClient(*gateway.address).connect() as client:
        client.request("start_recording", take="taken", timeout_s=60.0)  # generous deadlines, as above
        time.sleep(0.5)
        client.request("stop_recording", timeout_s=60.0)
    host, port = gateway.address
    code = console_main(["--connect", f"{host}:{port}", "--record", "taken", "--duration", "2",
                         "--save-poses", str(tmp_path / "p.npz")])
    err = capsys.readouterr().err
    assert code == 1 and "recording taken refused" in err and "already exists" in err
    assert console_main(["--connect", f"{host}:{port}", "--record", "x"]) == 2  # a scripted run needs --duration


def test_scripted_calibration_with_a_viewer_secret_is_refused_at_once(qapp, tmp_path, monkeypatch, capsys):
    """A viewer cannot calibrate or record: the console says so in one line right after connecting (before, the
    wizard's refusals were silent and the run hung until its 90 s calibration timeout)."""
    from gateway import auth
    from gateway.daemon import Gateway

    auth.write_secret_file(tmp_path / "operator.secret")
    auth.write_secret_file(tmp_path / "viewer.secret")
    monkeypatch.delenv("COURTSIDE_SECRET", raising=False)
    secrets = auth.Secrets.from_files(tmp_path / "operator.secret", tmp_path / "viewer.secret")
    gateway = Gateway([], listen=("127.0.0.6", 0), record_dir=tmp_path / "rec", secrets=secrets).start()
    try:
        host, port = gateway.address
        for script in (["--calibrate"], ["--record", "t1"]):
            code = console_main(["--connect", f"{host}:{port}", "--secret-file", str(tmp_path / "viewer.secret"),
                                 "--duration", "30", *script])
            err = capsys.readouterr().err
            assert code == 2 and "need the operator role" in err and "as a viewer" in err
        assert not (tmp_path / "rec" / "t1").exists()
    finally:
        gateway.stop()
