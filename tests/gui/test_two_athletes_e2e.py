"""Issue 20 "Done when": two athletes, separate processes. `courtside gateway --config court.toml` with two
`[[athletes]]` on 127.0.0.9 (three emulated stations replaying mocap on ptys) and `courtside console --connect`
offscreen: both skeletons move, each from its own sensors. Then the far athlete's sensors are swapped (he now
wears station 3, which replays a different clip) and only his skeleton changes.

Ground truth: alice's station replays CMU 16_05 (root speed 0.48 m/s), bob's first 16_45 (running, 3.98 m/s),
after the swap 16_01 (standing, 0.09 m/s). The motion graph places each synthesised pose on a path whose speed
follows the recognised clip, so each skeleton's mean root speed says whose sensors drove it."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np

from tests.gateway.court_setup import stop_gateway

HOST = "127.0.0.9"
SENSORS = lambda station: json.dumps([f"st{station}:{i}" for i in range(6)])  # noqa: E731


def court_toml(bob_station: int, bob_clip: str) -> str:
    return f"""listen = "{HOST}:0"
[stations]
emulate = 3
emulate_clips = ["16_32"]
[[athletes]]
name = "alice"
side = "near"
sensors = {SENSORS(1)}
clips = ["16_05"]
[[athletes]]
name = "bob"
side = "far"
sensors = {SENSORS(bob_station)}
clips = ["{bob_clip}"]
"""


def run_court(tmp_path, bob_station: int, bob_clip: str) -> dict[str, dict]:
    """Gateway + console processes; each athlete's saved poses: root speed (m/s), frames, sensors, athlete."""
    (tmp_path / "court.toml").write_text(court_toml(bob_station, bob_clip))
    gateway = subprocess.Popen([sys.executable, "-m", "gateway.cli", "gateway", "--config", "court.toml"],
                               cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = ""
        while not (match := re.match(rf"gateway listening on {re.escape(HOST)}:(\d+)", line)):
            line = gateway.stdout.readline()
            assert line or gateway.poll() is None, gateway.stderr.read()
        env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
        console = subprocess.run([sys.executable, "-m", "gateway.cli", "console", "--connect", f"{HOST}:{match[1]}",
                                  "--duration", "25", "--save-poses", "poses.npz"], cwd=tmp_path, env=env,
                                 capture_output=True, text=True, timeout=300)
        assert console.returncode == 0, console.stderr[-3000:]
    finally:
        stop_gateway(gateway)
    out = {}
    for path in (tmp_path / "poses.npz", tmp_path / "poses.bob.npz"):
        data = np.load(path)
        meta = json.loads(str(data["meta_json"]))
        root_xz = data["joint_positions_m"][:, 0, [0, 2]]
        speed = float(np.mean(np.linalg.norm(np.diff(root_xz, axis=0), axis=1)) * meta["rate_hz"])
        out[meta["athlete"]] = {"speed": speed, "frames": len(root_xz),
                                "stations": {s["stream"].split("/")[0] for s in meta["sensors"]}}
    return out


def test_each_skeleton_moves_from_its_own_sensors_and_a_swap_changes_only_that_one(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    before = run_court(tmp_path / "a", 2, "16_45")
    after = run_court(tmp_path / "b", 3, "16_01")
    print({"before": before, "after": after})
    for run in (before, after):
        assert set(run) == {"alice", "bob"} and all(r["frames"] > 300 for r in run.values())  # both move
        assert run["alice"]["stations"] == {"st1"}
    assert before["bob"]["stations"] == {"st2"} and after["bob"]["stations"] == {"st3"}
    assert before["bob"]["speed"] > 2.5 > after["bob"]["speed"]  # running, then standing: his skeleton changed
    assert abs(before["alice"]["speed"] - after["alice"]["speed"]) < 0.5  # hers did not
    assert before["alice"]["speed"] < 2.0 and before["bob"]["speed"] > before["alice"]["speed"] + 1.5
