"""End to end: emulated base station (StillSource) over a real pty -> gateway -> CalibrationService, driven by a
real TCP GatewayClient like the console; the recovered mounting matches the emulated one. With an
orientation-capable station (protocol v2, the emulators' filter error model) the record also holds each sensor's
yaw offset, as emulated."""
from __future__ import annotations

import time

import numpy as np
import pytest

from engine.mocap import quaternions
from firmware_protocol.emulator import StationConfig
from firmware_protocol.emulator.motion import StillSource, TraceSource
from gateway.calibration import CalibrationRecord, rotation_angle_deg
from gateway.calibration.service import CalibrationService
from gateway.client import GatewayClient, GatewayRequestError
from gateway.daemon import Gateway
from firmware_protocol.emulator.stations import start_emulated_station

from .conftest import RATE_HZ, with_orientation


def wait_for(predicate, timeout_s: float = 15.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.05)
    return False


def through_the_npose(client: GatewayClient, subject) -> dict:
    """Drive the wizard as the console does: assign the subject's sensors ("st1/i"), pass the placement check,
    wait for the N-pose capture, skip the tap; returns the state in review."""
    for i, sid in enumerate(subject.segments):
        client.calibration("assign", sensor=f"st1/{i}", segment=subject.segments[sid])
    assert client.calibration("confirm")["accepted"]  # -> placement
    assert wait_for(lambda: all(s["placement_ok"] for s in client.calibration("state")["sensors"].values()))
    assert client.calibration("confirm")["accepted"]  # -> npose, auto-start when still
    assert wait_for(lambda: client.calibration("state")["step"] == "tap")
    return client.calibration("confirm")["state"]  # skip the tap


def test_calibration_through_the_gateway(tmp_path, specs, subject):
    ids = list(subject.segments)  # "st0/i" in the fixture; the gateway names them "st1/i"
    world_from_sensor = np.stack([subject.world_from_sensor(sid) for sid in ids])  # standing in the N-pose
    motion = StillSource(len(ids), quaternions.from_matrix(world_from_sensor))
    station = start_emulated_station(StationConfig(station_id=1, n_sensors=len(ids), autostart=True, noise_g=0.004),
                                     motion=motion)
    service = CalibrationService(specs, pose="npose", records_dir=tmp_path / "records")
    try:
        with Gateway([station.path], listen=("127.0.0.1", 0), record_dir=tmp_path, status_interval_s=0.1,
                     calibration=service) as gw, GatewayClient(*gw.address).connect() as client:
            with pytest.raises(GatewayRequestError, match="unknown segment"):
                client.calibration("assign", sensor="st1/0", segment="tail")
            state = through_the_npose(client, subject)
            assert state["step"] == "review" and state["tap_skipped"] and state["quality"]["passed"]
            for i, sid in enumerate(ids):
                q = np.array(state["sensors"][f"st1/{i}"]["rotation_wxyz"])
                error = rotation_angle_deg(quaternions.to_matrix(q) @ subject.true_rotation[sid].T)
                assert error < 2.0, (sid, error)
            victim = tmp_path / "victim.json"
            victim.write_text("keep me")
            # issue 12: a client never names a path, and a name never escapes the records directory
            with pytest.raises(GatewayRequestError, match="not a path"):
                client.calibration("save", path=str(victim), subject="p1")
            for bad in ("../victim", "..", ".hidden", "a/b", "x\n", ""):
                with pytest.raises(GatewayRequestError, match="record name"):
                    client.calibration("save", name=bad, subject="p1")
            assert victim.read_text() == "keep me" and not (tmp_path / "victim.npz").exists()
            saved = client.calibration("save", name="p1-cal", subject="p1", take="t1")
            assert saved["json"] == str(tmp_path / "records" / "p1-cal.calibration.json")
            assert CalibrationRecord.load(saved["json"]).subject == "p1"
            with pytest.raises(GatewayRequestError, match="already exists"):
                client.calibration("save", name="p1-cal", subject="p1")
            assert sorted(p.name for p in (tmp_path / "records").iterdir()) == ["p1-cal.calibration.json",
                                                                                "p1-cal.calibration.npz"]
    finally:
        station.stop()


def test_orientation_calibration_through_the_gateway(tmp_path, specs, subject):
    """The subject's sensors on a station streaming orientations (MOTION_BATCH, quaternions quantised to Q14 on
    the wire) through the gateway's hook: the saved record holds every sensor's yaw offset -- relative to the
    pelvis sensor, what the emulated filters had in the middle of the capture (the record's raw sample times,
    mapped back to the emulator's own clock) within 1.5 deg -- and the engine reads it as an
    OrientationCalibration."""
    from engine.mocap import SEED000_SENSORS, load_sensor_calibration

    subject = with_orientation(subject, seed=9)
    ids = list(subject.segments)
    still = np.stack([subject.gravity_reading(sid) + subject.bias_g[sid] for sid in ids])
    frames = len(subject.quat_device)
    trace = TraceSource(np.broadcast_to(still, (frames,) + still.shape), RATE_HZ, subject.quat_device,
                        np.zeros((frames, len(ids), 3)))
    station = start_emulated_station(StationConfig(station_id=1, n_sensors=len(ids), autostart=True, noise_g=0.004,
                                                   orientation=True), motion=trace)
    service = CalibrationService(specs, pose="npose", records_dir=tmp_path / "records")
    try:
        with Gateway([station.path], listen=("127.0.0.1", 0), record_dir=tmp_path, status_interval_s=0.1,
                     calibration=service) as gw, GatewayClient(*gw.address).connect() as client:
            state = through_the_npose(client, subject)
            assert "orientation calibrated for 6 of 6 sensors" in " ".join(state["messages"])
            saved = client.calibration("save", name="oriented", subject="p1")
    finally:
        station.stop()
    record = CalibrationRecord.load(saved["json"])
    pelvis = next(i for i, sid in enumerate(ids) if subject.segments[sid] == "lower_back")
    yaw = np.array([record.sensors[f"st1/{i}"].orientation_yaw_rad for i in range(len(ids))])
    t_host = record.raw["npose"]["st1/0"][0]
    t_emulated = float(np.mean(t_host) - station.wall0_s) * station.speed
    known = np.array(list(subject.yaw_offsets_rad(t_emulated).values()))
    error = np.degrees(np.angle(np.exp(1j * ((yaw - yaw[pelvis]) - (known - known[pelvis])))))
    print(f"capture at emulator t = {t_emulated:.1f} s; solved - emulated yaw relative to the pelvis (deg):",
          np.round(error, 2))
    assert 0.0 < t_emulated < 30.0 and np.abs(error).max() < 1.5
    cal = load_sensor_calibration(saved["json"])
    order = [f"st1/{ids.index(next(s for s, seg in subject.segments.items() if seg == n))}" for n in SEED000_SENSORS]
    np.testing.assert_array_equal(cal.orientation_calibration(SEED000_SENSORS).yaw_rad,
                                  [record.sensors[sid].orientation_yaw_rad for sid in order])


def test_standard_service_uses_engine_placements_and_refuses_cleanly(tmp_path):
    from engine.mocap import SEED000_SENSORS
    from gateway.server import RequestError

    service = CalibrationService.standard(records_dir=tmp_path)
    assert set(service.state()["unassigned_segments"]) == set(SEED000_SENSORS)
    with pytest.raises(RequestError, match="needs argument 'segment'"):
        service.handle("assign", {"sensor": "st1/0"})
    with pytest.raises(RequestError, match="no N-pose captured"):
        service.handle("save", {"name": "x"})
    with pytest.raises(RequestError, match="unknown calibration action 'dance'"):
        service.handle("dance", {})
    service.handle("assign", {"sensor": "st1/0", "segment": "chest"})
    service.on_samples("st1", 0, np.arange(5) * 0.01, np.tile([0.0, 1.0, 0.0], (5, 1)))
    state = service.handle("reset", {})
    assert state["sensors"] == {} and state["step"] == "assign"
