"""Issue 13 "Done when": the gateway and the console as two processes on a non-default loopback address, with
authentication — the console calibrates through the client, records a take, stops, and `courtside synthesize`
on the recorded take reproduces the poses the console produced live, bit for bit.

Everything is real: `courtside gateway --config court.toml` (emulated stations on ptys replaying mocap — a still
N-pose lead-in so the wizard can capture, then held-out CMU walk and run —, the camera reading a rendered court
video whose calibration `courtside camera calibrate` wrote, the calibration wizard, operator/viewer secrets) on
127.0.0.2; `courtside console --calibrate --record --save-poses` offscreen as a second process authenticating
with the operator secret file (the wizard waits for the still phase of the replay loop, the 15 s take then holds
motion); `courtside gateway export` and `courtside synthesize` as further processes."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from engine.mocap import SEED000_SENSORS
from gateway import auth
from gateway.client import GatewayClient, GatewayRequestError
from tests.gateway.court_setup import courtside, make_court, start_gateway, stop_gateway

HOST = "127.0.0.2"
HELD_OUT = ("16_32", "16_36", "16_05")  # walk, run, jump: what the stations replay; not in the console's graph
STILL_S = 12.0  # each replay loop: the N-pose held this long, then ~13 s of motion
LAG_S = 0.5  # the same as tests.gui.test_live_equals_offline.LAG_S (its comparison helper is used here)


def console_process(*args: str, cwd, code: int = 0) -> subprocess.CompletedProcess:
    """`courtside console` as its own process, offscreen, with a cache of its own and no secret in the
    environment (it must read the secret file it is given); ``code`` is the exit code expected."""
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", COURTSIDE_CACHE_DIR=str(cwd / "cache"))
    env.pop("COURTSIDE_SECRET", None)
    env.pop("COURTSIDE_SECRET_FILE", None)
    result = subprocess.run([sys.executable, "-m", "gateway.cli", "console", *args], cwd=cwd, capture_output=True,
                            text=True, timeout=400, env=env)
    assert result.returncode == code, f"console: exit {result.returncode}\n{result.stderr[-3000:]}"
    return result


def write_still_npose_clip(path, seconds: float) -> None:
    """The calibration pose held still (the wizard's reference N-pose on the shipped skeleton), as a BVH clip the
    emulated stations replay before the motion."""
    from engine.mocap import Motion, load_clip, quaternions, sample_clips, write_bvh
    from gateway.calibration.pose import reference_npose

    clip = load_clip(sample_clips()["16_01"])
    local, _ = reference_npose(clip.skeleton)
    frames = int(30 * seconds)
    rotations = np.broadcast_to(quaternions.from_matrix(local), (frames, clip.skeleton.n_joints, 4)).copy()
    root = np.tile([0.0, clip.root_positions_m[0, 1], 0.0], (frames, 1))
    write_bvh(path, Motion(clip.skeleton, 30.0, root, rotations, "still-npose"))


@pytest.fixture()
def court(tmp_path):
    """The daemon's whole-court fixture (tests/gateway/court_setup.py) with the replay loop starting in the
    N-pose, the console (not the config) starting the take, and the court video looping for the longer session;
    plus a motion graph without the replayed clips."""
    from engine.graph.cli import build_graph_main
    from engine.mocap import sample_clips

    write_still_npose_clip(tmp_path / "still.bvh", STILL_S)
    make_court(tmp_path, listen=f"{HOST}:0", clips=("still.bvh",) + HELD_OUT + HELD_OUT[:1])
    config = (tmp_path / "court.toml").read_text()
    assert 'record = "match"\n' in config and "thumbnail_every = 5\n" in config
    (tmp_path / "court.toml").write_text(config.replace('record = "match"\n', "")
                                         .replace("thumbnail_every = 5\n", "thumbnail_every = 5\nloop = true\n"))
    graph_clips = [str(p) for n, p in sample_clips().items() if n.startswith("16_") and n not in HELD_OUT]
    assert build_graph_main(graph_clips + ["-o", str(tmp_path / "g.npz")]) == 0
    return tmp_path


@pytest.mark.slow
def test_gateway_and_console_as_two_processes_live_equals_offline(court):
    from engine.stream.poses_file import load_poses

    from tests.gui.test_live_equals_offline import compare_live_and_offline

    proc, port = start_gateway(court, "--config", "court.toml")
    try:
        # an unauthenticated client is refused; a viewer may watch but not control
        with pytest.raises(auth.AuthenticationError):
            GatewayClient(HOST, port).connect()
        with GatewayClient(HOST, port, secret=auth.read_secret_file(court / "viewer.secret")) as viewer:
            with pytest.raises(GatewayRequestError, match="needs the operator role"):
                viewer.start_recording("stolen")
            with pytest.raises(GatewayRequestError, match="needs the operator role"):
                viewer.calibration("assign", sensor="st1/0", segment="chest")
        refused = console_process("--connect", f"{HOST}:{port}", "--duration", "1", cwd=court, code=2)
        assert "cannot connect" in refused.stderr and "Traceback" not in refused.stderr  # no secret: no console
        console = console_process("--connect", f"{HOST}:{port}", "--secret-file", "operator.secret",
                                  "--graph", "g.npz", "--lag", str(LAG_S), "--calibrate", "--record", "e2e",
                                  "--duration", "15", "--save-poses", "live.npz", cwd=court)
        assert "calibration record saved" in console.stderr
        with GatewayClient(HOST, port, secret=auth.read_secret_file(court / "operator.secret")) as operator:
            assert not operator.status()["recording"]["active"]
    finally:
        stop_gateway(proc)
    record = json.loads((court / "calibrations" / "e2e.calibration.json").read_text())
    assert set(SEED000_SENSORS) <= {s["segment"] for s in record["sensors"].values()}
    courtside("gateway", "export", "takes/e2e", "--npz", "take.npz", cwd=court)
    with np.load(court / "take.npz") as take:  # the take holds motion, not only the calibration pose
        assert np.linalg.norm(take["st1/0/acc_g"], axis=1).std() > 0.1
    live = load_poses(court / "live.npz")
    assert live.meta["take"] == "e2e" and live.meta["database"] == "g.npz"
    sensor_map = [f"{s['stream']}={s['placement']}" for s in live.meta["sensors"]]
    courtside("synthesize", "--graph", "g.npz", "--input", "take.npz", "-o", "take.bvh", "--lag", str(LAG_S),
              "--sensor-map", *sensor_map, "--save-poses", "offline.npz", cwd=court)
    assert compare_live_and_offline(court / "live.npz", court / "offline.npz") > 150
    offline = load_poses(court / "offline.npz")
    assert offline.meta["frames_with_camera"] > 100 and offline.meta["frames_invalid"] == 0
