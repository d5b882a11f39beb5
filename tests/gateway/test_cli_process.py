"""`courtside gateway` as a real process: emulated stations, status lines, a client, SIGTERM -> clean stop with
an intact recording."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time

from gateway.client import GatewayClient
from gateway.recorder import load_take


def test_cli_emulate_record_and_sigterm(tmp_path):
    cmd = [sys.executable, "-m", "gateway.cli", "gateway", "--emulate", "2", "--listen", "127.0.0.1:0",
           "--record-dir", str(tmp_path), "--record", "cli-take", "--log-level", "WARNING"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines = []
    try:
        port = None
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            assert line, f"gateway exited early: {proc.stderr.read()}"
            lines.append(line)
            if match := re.match(r"gateway listening on 127\.0\.0\.1:(\d+)", line):
                port = int(match[1])
            if port and sum("streaming" in x for x in lines) >= 2:
                break
        assert port, lines
        with GatewayClient("127.0.0.1", port) as client:
            stations = client.list_stations()
            assert sorted(s["station"] for s in stations) == ["st1", "st2"]
            assert client.status()["recording"]["take"] == "cli-take"
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 0, err
    assert "gateway stopped" in out
    status_lines = [x for x in lines if re.match(r"\s+st[12] streaming\s+6 sensors", x)]
    assert status_lines, lines
    take = load_take(tmp_path / "cli-take")
    assert take.problem is None
    assert {key[0] for key in take.samples} == {"st1", "st2"}
    assert all(len(cols["counter"]) > 50 for cols in take.samples.values())
