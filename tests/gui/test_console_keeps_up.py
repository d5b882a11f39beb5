"""Issue 21: the console with four worn sensors (the OLNG, its default) runs two minutes of a real walk streamed
by emulated stations through a real gateway, and never reports FALLING BEHIND.

Real parts and the real topology: `courtside gateway --config court.toml` is its own process (as on the board
beside the court) on a non-default loopback address; its emulated base station behind a pty plays the virtual
accelerometers, orientations and angular rates of a shipped walk at the four seed-003 sites of the one athlete
the config names; `courtside console` runs here headless (Qt offscreen) with its synthesis worker. What keeps it
in time on a busy 2-core box is the engine's own effort control (engine/olng/keep_up.py): the test holds whatever
the machine's load."""
from __future__ import annotations

import json
import logging

import numpy as np
import pytest

from engine.mocap import SEED003_SENSORS
from gui.cli import console_main
from tests.gateway.court_setup import start_gateway, stop_gateway

RUN_S = 120
HOST = "127.0.0.13"
COURT = f"""listen = "{HOST}:0"
[stations]
emulate = 1
emulate_orientation = true
[[athletes]]
name = "walker"
sensors = {json.dumps([f"st1:{i}" for i in range(len(SEED003_SENSORS))])}
placements = {json.dumps(list(SEED003_SENSORS))}
clips = ["16_32"]
"""


@pytest.mark.slow  # two minutes of real time
@pytest.mark.alone  # it measures keeping up: another test beside it would take its core
def test_four_sensor_console_never_falls_behind_in_two_minutes(qapp, tmp_path, caplog):
    (tmp_path / "court.toml").write_text(COURT)
    gateway, port = start_gateway(tmp_path, "--config", "court.toml", mode="no authentication: loopback only")
    poses = tmp_path / "poses.npz"
    try:
        with caplog.at_level(logging.INFO, logger="courtside.console"):
            assert console_main(["--connect", f"{HOST}:{port}", "--duration", str(RUN_S),
                                 "--save-poses", str(poses)]) == 0
    finally:
        stop_gateway(gateway)
    assert "engine olng (default for 4 worn sensors)" in caplog.text
    assert "FALLING BEHIND" not in caplog.text
    from engine.stream.poses_file import load_poses

    saved = load_poses(poses)
    # every frame of the run was synthesised (the engine starts once the first samples arrive: a few s of slack)
    assert len(saved.t_s) > 25 * (RUN_S - 10) and np.isfinite(saved.joint_positions_m).all()
