"""Two athletes, one calibration wizard each (issue 20), through a real gateway and TCP client: alice calibrates
(emulated still subject on station 1) while bob's station 2 keeps streaming; samples carry their athlete, bob's
wizard never sees alice's sensors, and alice's saved record names her."""
from __future__ import annotations

import numpy as np
import pytest

from engine.mocap import quaternions
from firmware_protocol.emulator import StationConfig
from firmware_protocol.emulator.motion import StillSource
from gateway.athletes import AthleteConfig, AthleteMap, SensorRef
from gateway.calibration import CalibrationRecord, rotation_angle_deg
from gateway.calibration.athletes import AthleteCalibrations
from gateway.calibration.service import CalibrationService
from gateway.client import GatewayClient, GatewayRequestError
from gateway.daemon import Gateway
from firmware_protocol.emulator.stations import start_emulated_station

from .test_gateway_hook import wait_for


def test_one_wizard_per_athlete_while_the_other_streams(tmp_path, specs, subject):
    ids = list(subject.segments)
    n = len(ids)
    world_from_sensor = np.stack([subject.world_from_sensor(sid) for sid in ids])
    stations = [start_emulated_station(StationConfig(station_id=k, n_sensors=n, autostart=True, noise_g=0.004),
                                       motion=StillSource(n, quaternions.from_matrix(world_from_sensor)))
                for k in (1, 2)]
    athletes = AthleteMap([AthleteConfig("alice", "near", tuple(SensorRef("st", 1, i) for i in range(n))),
                           AthleteConfig("bob", "far", tuple(SensorRef("st", 2, i) for i in range(n)))])
    hook = AthleteCalibrations({name: CalibrationService(specs, pose="npose", records_dir=tmp_path / "records")
                                for name in ("alice", "bob")})
    try:
        with Gateway([s.path for s in stations], listen=("127.0.0.9", 0), record_dir=tmp_path,
                     status_interval_s=0.1, calibration=hook, athletes=athletes) as gw, \
                GatewayClient(*gw.address).connect() as client:
            tagged: dict[str, set] = {}
            client.add_listener("samples", lambda m: tagged.setdefault(m["station"], set()).add(m.header["athlete"]))
            client.subscribe(["samples"])
            assert [a["name"] for a in client.server_hello["athletes"]] == ["alice", "bob"]
            for i, sid in enumerate(ids):
                client.calibration("assign", athlete="alice", sensor=f"st1/{i}", segment=subject.segments[sid])
                client.calibration("assign", athlete="bob", sensor=f"st1/{i}", segment=subject.segments[sid])
            with pytest.raises(GatewayRequestError, match="no athlete 'carol'"):
                client.calibration("state", athlete="carol")
            assert client.calibration("confirm", athlete="alice")["accepted"]
            assert client.calibration("confirm", athlete="bob")["accepted"]
            alice_ok = lambda: all(s["placement_ok"] for s in client.calibration("state")["sensors"].values())  # noqa: E731
            assert wait_for(alice_ok)  # default athlete: the first (alice)
            bob = client.calibration("state", athlete="bob")
            assert bob["athlete"] == "bob" and not any(s["placement_ok"] for s in bob["sensors"].values())
            assert client.calibration("confirm", athlete="alice")["accepted"]  # -> npose
            assert wait_for(lambda: client.calibration("state")["step"] == "tap")
            state = client.calibration("confirm", athlete="alice")["state"]  # skip the tap
            assert state["step"] == "review" and state["quality"]["passed"]
            for i, sid in enumerate(ids):
                q = np.array(state["sensors"][f"st1/{i}"]["rotation_wxyz"])
                assert rotation_angle_deg(quaternions.to_matrix(q) @ subject.true_rotation[sid].T) < 2.0
            saved = client.calibration("save", athlete="alice", name="alice-cal")
            assert saved["athlete"] == "alice" and CalibrationRecord.load(saved["json"]).subject == "alice"
            whole = client.calibration("state")
            assert set(whole["athletes"]) == {"alice", "bob"} and whole["athletes"]["bob"]["step"] == "placement"
            assert wait_for(lambda: {"st1", "st2"} <= set(tagged))
            assert tagged["st1"] == {"alice"} and tagged["st2"] == {"bob"}  # bob kept streaming, as bob
    finally:
        for station in stations:
            station.stop()
