"""`courtside gateway --config court.toml` as a real process on 127.0.0.2 with everything a court has: emulated
stations replaying mocap on ptys, the camera reading a rendered court video whose calibration the court
calibration CLI wrote, the calibration wizard, authentication with operator and viewer secrets, a recording that
continues into a suffixed take after a restart (issue 13)."""
from __future__ import annotations

import os
import re

import numpy as np
import pytest

from engine.mocap import SEED000_SENSORS
from gateway import auth
from gateway.client import GatewayClient, GatewayRequestError
from gateway.recorder import load_take
from tests.gateway.court_setup import make_court, start_gateway, stop_gateway, wait_for


@pytest.fixture()
def court_dir(tmp_path):
    return make_court(tmp_path)


def test_gateway_config_runs_a_whole_court(court_dir):
    operator_secret = auth.read_secret_file(court_dir / "operator.secret")
    viewer_secret = auth.read_secret_file(court_dir / "viewer.secret")
    proc, port = start_gateway(court_dir, "--config", "court.toml")
    try:
        with GatewayClient("127.0.0.2", port, secret=operator_secret) as op, \
                GatewayClient("127.0.0.2", port, secret=viewer_secret) as viewer:
            assert op.role == "operator" and viewer.role == "viewer"
            # stations replay mocap: the worn sensors move (not the flat lines of issue 13)
            status = wait_for(lambda: (s := op.status()) and len(s["stations"]) == 2 and all(
                st["link"] == "streaming" for st in s["stations"]) and s)
            assert sorted(len(st["sensors"]) for st in status["stations"]) == [5, 6]
            samples = []
            op.add_listener("samples", lambda m: samples.append(m) if m["station"] == "st1" else None)
            # waits poll until the condition holds (a loaded machine only makes them slower), then judge the data
            wait_for(lambda: sum(len(m["acc_g"]) for m in list(samples) if m["sensor"] == 0) > 200)
            acc = np.concatenate([m["acc_g"] for m in list(samples) if m["sensor"] == 0])
            assert np.linalg.norm(acc, axis=1).std() > 0.1
            # the camera runs in the gateway: health in status, tracked observations streamed to clients; its rate
            # is measured over the last 2 s, so a moment of CPU starvation dips it: wait for a healthy window
            camera = wait_for(lambda: (c := viewer.status()["camera"]) and c["tracked"] > 10 and c["fps"] > 5 and c)
            assert camera["state"] == "running" and camera["source"].endswith("court.mp4")
            observation = viewer.get(timeout_s=30.0, kinds=["camera"])
            assert observation is not None and "t_host_s" in observation.header
            # calibration is attached: the operator assigns, the viewer may only look
            for i, site in enumerate(SEED000_SENSORS):
                op.calibration("assign", sensor=f"st1/{i}", segment=site)
            state = viewer.calibration("state")
            assert {s["segment"] for s in state["sensors"].values() if s.get("segment")} == set(SEED000_SENSORS)
            with pytest.raises(GatewayRequestError, match="needs the operator role"):
                viewer.calibration("reset")
            with pytest.raises(GatewayRequestError, match="not a path"):
                op.calibration("save", path=str(court_dir / "court.toml"))
            # recording started from the config; only the operator may stop it
            with pytest.raises(GatewayRequestError, match="needs the operator role"):
                viewer.stop_recording()
            with pytest.raises(auth.AuthenticationError):
                GatewayClient("127.0.0.2", port).connect()
            final = op.stop_recording()
            assert final["take"] == "match" and final["samples_written"] > 500
    finally:
        out, err = stop_gateway(proc)
    assert re.search(r"camera running\s+\d+\.\d fps .* tracking, confidence", out), out
    take = load_take(court_dir / "takes" / "match")
    assert take.problem is None and {k[0] for k in take.samples} == {"st1", "st2"}
    assert sum(m.kind == "camera" and "position_m" in m.header for m in take.others) > 10

    # restarted by a service manager with the same --record: a new take, not a refusal or a traceback
    proc, port = start_gateway(court_dir, "--config", "court.toml", "--camera-loop")
    try:
        with GatewayClient("127.0.0.2", port, secret=operator_secret) as op:
            assert op.status()["recording"]["take"] == "match-2"
    finally:
        out, _ = stop_gateway(proc)
    assert sorted(p.name for p in (court_dir / "takes").iterdir()) == ["match", "match-2"]
    assert not os.path.exists(court_dir / "calibrations")  # nothing saved, nothing written
