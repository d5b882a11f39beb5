"""docs/deploy/two-athletes.emulated.toml is a ready court (issue 30): `courtside gateway --config` runs it as a
process (two emulated stations, one per athlete), a `courtside console` process connects and synthesizes each
athlete from its own station, and the gateway logs each station's hello once and its listening line once;
`--quiet` leaves warnings only."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from tests.gateway.court_setup import start_gateway, stop_gateway

CONFIG = Path(__file__).resolve().parents[2] / "docs" / "deploy" / "two-athletes.emulated.toml"


def test_the_two_athlete_court_config_runs_a_gateway_and_a_console(tmp_path):
    gateway, port = start_gateway(tmp_path, "--config", str(CONFIG), "--listen", "127.0.0.1:0", "--record-dir",
                                  str(tmp_path / "rec"), mode="no authentication")
    try:
        console = subprocess.run([sys.executable, "-m", "gateway.cli", "console", "--connect", f"127.0.0.1:{port}",
                                  "--duration", "8", "--save-poses", "poses.npz"], cwd=tmp_path, capture_output=True,
                                 text=True, timeout=300, env=dict(os.environ, QT_QPA_PLATFORM="offscreen"))
        assert console.returncode == 0, console.stderr[-3000:]
    finally:
        out, err = stop_gateway(gateway)
    worn = {}
    for path in (tmp_path / "poses.npz", tmp_path / "poses.bob.npz"):
        data = np.load(path)
        meta = json.loads(str(data["meta_json"]))
        assert len(data["joint_positions_m"]) > 30 and np.isfinite(data["joint_positions_m"]).all()
        worn[meta["athlete"]] = {s["stream"].split("/")[0] for s in meta["sensors"]}
    assert worn == {"alice": {"st1"}, "bob": {"st2"}}
    for station in ("st1", "st2"):
        assert err.count(f"{station}: hello: firmware") == 1, err
    assert "gateway listening" not in out + err  # printed once, the line start_gateway read; not logged again


def test_gateway_quiet_prints_no_info(tmp_path):
    gateway, _ = start_gateway(tmp_path, "--emulate", "1", "--emulate-motion", "none", "--listen", "127.0.0.1:0",
                               "--record-dir", str(tmp_path), "--quiet", mode="no authentication")
    out, err = stop_gateway(gateway)
    assert " INFO " not in err and "streaming" not in out, (out, err)
