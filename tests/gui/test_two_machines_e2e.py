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
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from engine.mocap import SEED000_SENSORS
from gateway import auth
from gateway.client import GatewayClient, GatewayRequestError

HOST = "127.0.0.2"
SIZE = (480, 270)
HELD_OUT = ("16_32", "16_36", "16_05")  # walk, run, jump: what the stations replay; not in the console's graph
STILL_S = 12.0  # each replay loop: the N-pose held this long, then ~13 s of motion
LAG_S = 0.5  # the same as tests.gui.test_live_equals_offline.LAG_S (its comparison helper is used here)


def courtside(*args: str, cwd, timeout_s: float = 300, env=None) -> subprocess.CompletedProcess:
    result = subprocess.run([sys.executable, "-m", "gateway.cli", *args], cwd=cwd, capture_output=True, text=True,
                            timeout=timeout_s, env=env)
    assert result.returncode == 0, f"courtside {' '.join(args)}: {result.returncode}\n{result.stderr[-3000:]}"
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
    from engine.graph.cli import build_graph_main
    from engine.mocap import sample_clips
    from gateway.camera.court import COURT_KEYPOINTS_M, keypoints_array
    from gateway.camera.synthetic import default_court_camera

    courtside("camera", "synth", "--out", "court.mp4", "--calibration", "synth_court.json", "--truth", "truth.csv",
              "--seconds", "10", "--fps", "15", "--width", str(SIZE[0]), "--height", str(SIZE[1]), cwd=tmp_path)
    camera = default_court_camera(SIZE)
    names = list(COURT_KEYPOINTS_M)
    clicks = camera.project(np.column_stack([keypoints_array(names), np.zeros(len(names))]))
    (tmp_path / "clicks.json").write_text(json.dumps({n: c.tolist() for n, c in zip(names, clicks)}))
    courtside("camera", "calibrate", "--clicks", "clicks.json", "--image-size", *map(str, SIZE),
              "--focal-px", str(camera.camera_matrix[0, 0]), "--out", "court.json", cwd=tmp_path)
    for name in ("operator.secret", "viewer.secret"):
        auth.write_secret_file(tmp_path / name)
    write_still_npose_clip(tmp_path / "still.bvh", STILL_S)
    placements = ", ".join(f'"{s}"' for s in SEED000_SENSORS)
    clips = ", ".join(f'"{c}"' for c in ("still.bvh",) + HELD_OUT + HELD_OUT[:1])
    (tmp_path / "court.toml").write_text(f"""
listen = "{HOST}:0"
record_dir = "takes"
log_level = "info"
status_interval_s = 0.5
clock_lock_after_s = 3

[stations]
emulate = 2
emulate_clips = [{clips}]

[camera]
source = "court.mp4"
court = "court.json"
player_side = "near"
loop = true

[calibration]
placements = [{placements}]
records_dir = "calibrations"

[auth]
operator_secret_file = "operator.secret"
viewer_secret_file = "viewer.secret"
""")
    graph_clips = [str(p) for n, p in sample_clips().items() if n.startswith("16_") and n not in HELD_OUT]
    assert build_graph_main(graph_clips + ["-o", str(tmp_path / "g.npz")]) == 0
    return tmp_path


def start_gateway(cwd) -> tuple[subprocess.Popen, int]:
    proc = subprocess.Popen([sys.executable, "-m", "gateway.cli", "gateway", "--config", "court.toml"], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        assert line, f"gateway exited early ({proc.poll()})"
        if match := re.match(rf"gateway listening on {re.escape(HOST)}:(\d+) \(authentication required", line):
            return proc, int(match[1])
    proc.kill()
    raise AssertionError("gateway did not start")


@pytest.mark.slow
def test_gateway_and_console_as_two_processes_live_equals_offline(court):
    from engine.stream.poses_file import load_poses

    from tests.gui.test_live_equals_offline import compare_live_and_offline

    proc, port = start_gateway(court)
    try:
        # an unauthenticated client is refused; a viewer may watch but not control
        with pytest.raises(auth.AuthenticationError):
            GatewayClient(HOST, port).connect()
        with GatewayClient(HOST, port, secret=auth.read_secret_file(court / "viewer.secret")) as viewer:
            with pytest.raises(GatewayRequestError, match="needs the operator role"):
                viewer.start_recording("stolen")
            with pytest.raises(GatewayRequestError, match="needs the operator role"):
                viewer.calibration("assign", sensor="st1/0", segment="chest")
        env = dict(os.environ, QT_QPA_PLATFORM="offscreen", COURTSIDE_CACHE_DIR=str(court / "cache"))
        env.pop("COURTSIDE_SECRET", None)
        console = courtside("console", "--connect", f"{HOST}:{port}", "--secret-file", "operator.secret",
                            "--graph", "g.npz", "--lag", str(LAG_S), "--calibrate", "--record", "e2e",
                            "--duration", "15", "--save-poses", "live.npz", cwd=court, env=env, timeout_s=400)
        assert "calibration record saved" in console.stderr
        status = GatewayClient(HOST, port, secret=auth.read_secret_file(court / "operator.secret")).connect()
        with status:
            assert not status.status()["recording"]["active"]
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(30)
        finally:
            if proc.poll() is None:
                proc.kill()
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
