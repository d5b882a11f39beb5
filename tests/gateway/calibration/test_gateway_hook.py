"""End to end: emulated base station (StillSource) over a real pty -> gateway -> CalibrationService, driven by a
real TCP GatewayClient like the console; the recovered mounting matches the emulated one."""
from __future__ import annotations

import time

import numpy as np
import pytest

from engine.mocap import quaternions
from firmware_protocol.emulator import StationConfig
from firmware_protocol.emulator.motion import StillSource
from gateway.calibration import CalibrationRecord, rotation_angle_deg
from gateway.calibration.service import CalibrationService
from gateway.client import GatewayClient, GatewayRequestError
from gateway.daemon import Gateway
from firmware_protocol.emulator.stations import start_emulated_station


def wait_for(predicate, timeout_s: float = 15.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.05)
    return False


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
            for i, sid in enumerate(ids):
                client.calibration("assign", sensor=f"st1/{i}", segment=subject.segments[sid])
            with pytest.raises(GatewayRequestError, match="unknown segment"):
                client.calibration("assign", sensor="st1/0", segment="tail")
            assert client.calibration("confirm")["accepted"]  # -> placement
            assert wait_for(lambda: all(s["placement_ok"] for s in client.calibration("state")["sensors"].values()))
            assert client.calibration("confirm")["accepted"]  # -> npose, auto-start when still
            assert wait_for(lambda: client.calibration("state")["step"] == "tap")
            state = client.calibration("confirm")["state"]  # skip the tap
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
