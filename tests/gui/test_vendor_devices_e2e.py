"""Issue 15 "Done when": devices people can buy, worn by one subject, through the whole system as separate
processes — `courtside gateway --config court.toml` reads three x-IMU3s (binary mode, the factory default) and
three Shimmer3s through the vendors' own libraries (emulators on ptys in this process, all replaying one
standing-then-walking take of virtual sensors strapped 20-30 deg off nominal); `courtside console` records a take;
`courtside gateway export` + `courtside calibrate --sensor-map` turn that recording into the wizard's record with
the live sensor ids; a second `courtside console --calibration ... --stream-vmc` synthesises live from the six
devices (no station holds them all: the record says which is where) and streams the skeleton to a real VMC
(OSC/UDP) receiver on 127.0.0.1."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from engine.mocap import SEED000_SENSORS, standard_placements, virtual_accelerometers
from gateway import auth
from gateway.client import GatewayClient
from bench.support.imu_formats import mounted, standing_then_walking
from tests.gateway.court_setup import courtside, start_gateway, stop_gateway, wait_for

XIMU3 = {"left_forearm": "0000A001", "left_shin": "0000A002", "lower_back": "0000A003"}
SHIMMER = {"right_forearm": "R1", "right_shin": "R2", "chest": "R3"}
SHIMMER_HZ = 32768 / 320  # 102.4 Hz, a whole number of the Shimmer's 32768 Hz ticks
LEAD_S = 1.0  # the subject stands this long into a take before the replayed motion starts
HOLD = 1e6  # origin far in the future: every device replays the first (standing) reading


def _readings(fps: float):
    """Per placement (T, 3) g as the mounted sensors read the take at ``fps`` (+0.01 g noise), the mountings,
    and the take's length."""
    motion = standing_then_walking(walks=("16_11", "16_16"), fps=fps)
    truth = mounted(standard_placements(motion.skeleton, list(SEED000_SENSORS)), seed=3)
    acc = virtual_accelerometers(motion, truth)
    acc = acc + np.random.default_rng(7).normal(0.0, 0.01, acc.shape)
    return {p.name: acc[:, k] for k, p in enumerate(truth)}, {p.name: p for p in truth}, motion.n_frames / fps


def _record_in_step(court, port: int, secret: bytes, devices, *console_args: str, duration_s: float):
    """`courtside console ... --record` as its own process; once the gateway says the take is recording, every
    device starts the motion (after LEAD_S of standing). Returns the console's CompletedProcess."""
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", COURTSIDE_CACHE_DIR=str(court / "cache"))
    env.pop("COURTSIDE_SECRET", None)
    env.pop("COURTSIDE_SECRET_FILE", None)
    for d in devices:
        d.origin_s = time.monotonic() + HOLD
    proc = subprocess.Popen([sys.executable, "-m", "gateway.cli", "console", "--connect", f"127.0.0.1:{port}",
                             "--secret-file", "operator.secret", *console_args, "--duration", f"{duration_s:g}"],
                            cwd=court, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        with GatewayClient("127.0.0.1", port, secret=secret) as client:
            wait_for(lambda: client.status()["recording"]["active"] or proc.poll() is not None, 120.0)
        start = time.monotonic() + LEAD_S
        for d in devices:
            d.origin_s = start
        out, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err[-3000:]
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


@pytest.mark.slow
@pytest.mark.alone  # the live console must keep up with six stations (>= 80 % of the poses): a test beside it starves it
def test_bought_devices_record_calibrate_and_drive_the_console_with_vmc_out(tmp_path):
    pytest.importorskip("ximu3")
    pytest.importorskip("pyshimmer")
    pytest.importorskip("pythonosc")
    from pythonosc.dispatcher import Dispatcher
    from pythonosc.osc_server import ThreadingOSCUDPServer

    from engine.graph.cli import build_graph_main
    from engine.stream.poses_file import load_poses
    from gateway.calibration import rotation_angle_deg
    from gateway.recorder import load_take
    from firmware_protocol.emulator.shimmer_device import ShimmerEmulator
    from firmware_protocol.emulator.ximu3_device import Ximu3Emulator

    x_acc, truth, length_s = _readings(100.0)
    s_acc, _, _ = _readings(SHIMMER_HZ)
    devices = [Ximu3Emulator(name=p, serial=sn, acc_g=x_acc[p], seed=i) for i, (p, sn) in enumerate(XIMU3.items())]
    devices += [ShimmerEmulator(name=n, rate_hz=SHIMMER_HZ, acc_g=s_acc[p], seed=i) for i, (p, n) in
                enumerate(SHIMMER.items())]
    station = {**{p: f"ximu3-{sn}/0" for p, sn in XIMU3.items()}, **{p: f"shimmer3-{n}/0" for p, n in SHIMMER.items()}}
    for name in ("operator.secret", "viewer.secret"):
        auth.write_secret_file(tmp_path / name)
    ports = ", ".join(f'"{prefix}:{d.path}"' for prefix, d in zip(["ximu3"] * 3 + ["shimmer"] * 3, devices))
    (tmp_path / "court.toml").write_text(f"""
listen = "127.0.0.1:0"
record_dir = "takes"
log_level = "warning"
status_interval_s = 60  # the test reads the gateway's stdout only up to "listening"

[stations]
ports = [{ports}]

[auth]
operator_secret_file = "operator.secret"
viewer_secret_file = "viewer.secret"
""")
    assert build_graph_main(["--sample", "-o", str(tmp_path / "g.npz")]) == 0
    secret = auth.read_secret_file(tmp_path / "operator.secret")
    vmc_t: list[float] = []
    dispatcher = Dispatcher()
    dispatcher.map("/VMC/Ext/T", lambda address, t: vmc_t.append(t))
    receiver = ThreadingOSCUDPServer(("127.0.0.1", 0), dispatcher)
    threading.Thread(target=receiver.serve_forever, daemon=True).start()
    for d in devices:
        d.start()
    proc, port = start_gateway(tmp_path, "--config", "court.toml")
    try:
        with GatewayClient("127.0.0.1", port, secret=secret) as client:
            names = {k.rsplit("/", 1)[0] for k in station.values()}  # a station is named once its device answers
            wait_for(lambda: {s["station"] for s in client.list_stations()} == names, 60.0)
            listed = {s["station"]: s for s in client.list_stations()}
        assert all(s["device_clock"] for s in listed.values())
        # 1. a plain take through the console: the subject stands, then walks (no database named: nothing says yet
        # which live sensors the graph's six are, and a console asked for a database it cannot wire refuses)
        _record_in_step(tmp_path, port, secret, devices, "--record", "cal",
                        duration_s=LEAD_S + length_s + 1.0)
        # 2. calibrate from that recording; the record names the live sensors
        courtside("gateway", "export", "takes/cal", "--npz", "cal.npz", cwd=tmp_path)
        result = courtside("calibrate", "cal.npz", "-o", "cal.calibration.json", "--sensor-map",
                           *(f"{sid}={p}" for p, sid in station.items()), cwd=tmp_path)
        summary = json.loads(result.stdout.strip().splitlines()[-1])
        assert set(summary["sensors"]) == set(station.values())
        record = json.loads((tmp_path / "cal.calibration.json").read_text())
        # 3. live synthesis from the six devices, the skeleton out as VMC
        live = _record_in_step(tmp_path, port, secret, devices, "--graph", "g.npz", "--calibration",
                               "cal.calibration.json", "--lag", "0.5", "--record", "live", "--save-poses",
                               "live.npz", "--stream-vmc", f"127.0.0.1:{receiver.server_address[1]}",
                               duration_s=LEAD_S + length_s)
    finally:
        stop_gateway(proc)
        receiver.shutdown()
        for d in devices:
            d.stop()
    assert "VMC (OSC/UDP) to 127.0.0.1" in live.stderr
    from gateway.calibration import CalibrationRecord

    measured = CalibrationRecord.load(tmp_path / "cal.calibration.json")
    errors = {s.segment: rotation_angle_deg(s.rotation @ truth[s.segment].rotation.T)
              for s in measured.sensors.values()}
    # gravity and the walking axis from the gateway's own recording of the devices (as from an imported file:
    # bench/bench_calibrate.py gives pelvis and shins 1.8-3.4 deg on these CMU walks)
    assert max(errors[p] for p in ("lower_back", "left_shin", "right_shin")) < 5.0, errors
    assert {s["segment"] for s in record["sensors"].values()} == set(SEED000_SENSORS)
    take = load_take(tmp_path / "takes" / "live")
    counts = {key[0]: len(cols["t_host_s"]) for key, cols in take.samples.items()}
    assert set(counts) == {k.rsplit("/", 1)[0] for k in station.values()}
    assert min(counts.values()) > 0.8 * 100 * length_s, counts  # both families recorded the whole walk
    pyxdf = pytest.importorskip("pyxdf")  # the same recording as XDF, one stream per device
    courtside("gateway", "export", "takes/live", "--xdf", "live.xdf", cwd=tmp_path)
    streams, _ = pyxdf.load_xdf(str(tmp_path / "live.xdf"), synchronize_clocks=False, dejitter_timestamps=False)
    by_type = {kind: {s["info"]["name"][0].split()[1]: len(s["time_stamps"]) for s in streams
                      if s["info"]["type"][0] == kind} for kind in ("Accelerometer", "Orientation")}
    assert by_type["Accelerometer"] == counts
    # the x-IMU3s also recorded their gyroscope and AHRS quaternion (the Shimmer3s here have no gyro enabled)
    assert by_type["Orientation"] == {k: n for k, n in counts.items() if k.startswith("ximu3")}
    poses = load_poses(tmp_path / "live.npz")
    assert {s["stream"] for s in poses.meta["sensors"]} == set(station.values())  # read across six stations
    assert len(poses.frame) > 0.8 * poses.meta["rate_hz"] * length_s
    wait_for(lambda: len(vmc_t) >= len(poses.frame), 5.0)
    assert len(vmc_t) == len(poses.frame) and vmc_t == sorted(vmc_t)  # every live pose went out as one bundle
    root = poses.joint_positions_m[:, 0]
    walked_m = np.linalg.norm(root[-1, [0, 2]] - root[0, [0, 2]])
    assert walked_m > 3.0, walked_m  # the subject walked (CMU 16_11 + 16_16: ~8 m); standing would stay put
