"""Two base stations announcing one station id (issue 22, item 5): they used to be merged silently into one
stream (repeated counters, time stepping back) that could not be separated afterwards. Now the second link is
re-keyed ``st<id>-dup2`` with an alarm, and both are recorded as separate streams. Real emulated stations on
ptys, a real gateway, a real recording."""
from __future__ import annotations

import time

import numpy as np

from gateway.client import GatewayClient
from gateway.daemon import Gateway
from firmware_protocol.emulator.stations import demo_config, start_emulated_station
from gateway.recorder import load_take

from .test_station_reader import wait_for


def test_two_stations_with_one_id_are_recorded_separately_with_an_alarm(tmp_path):
    rng = np.random.default_rng(5)
    # same station id 7, different serials, crystals and seeds: two physical boxes configured alike
    stations = [start_emulated_station(demo_config(i, rng, station_id=7, radio_loss=0.0, byte_corruption=0.0))
                for i in range(2)]
    gw = Gateway([], listen=("127.0.0.9", 0), record_dir=tmp_path, status_interval_s=0.5)
    try:
        gw.start()
        with GatewayClient(*gw.address) as client:
            client.subscribe(["event"])
            for s in stations:
                gw.add_station(s.path)
            assert wait_for(lambda: sorted(r.name for r in gw.readers) == ["st7", "st7-dup2"], timeout_s=20)
            client.start_recording("dup")
            time.sleep(2.0)
            client.stop_recording()
            events = [m for m in client.drain() if m.kind == "event"]
        alarms = [e for e in events if e["level"] == "alarm" and "announce station id 'st7'" in e["message"]]
        assert len(alarms) == 1 and alarms[0]["source"] == "st7-dup2" and alarms[0]["renamed_to"] == "st7-dup2"
        assert {s["station"] for s in client_status(gw)} == {"st7", "st7-dup2"}
    finally:
        gw.stop()
        for s in stations:
            s.stop()
    take = load_take(tmp_path / "dup")
    per_station = {st: [k for k in take.samples if k[0] == st] for st in ("st7", "st7-dup2")}
    assert all(per_station.values()), take.samples.keys()
    for station, keys in per_station.items():
        for key in keys:  # each stream is one station's own: counters strictly increase, time never steps back
            counter = take.samples[key]["counter"].astype(np.int64)
            assert len(counter) > 50 and np.all(np.diff(counter) > 0), (key, counter[:20])
            assert np.all(np.diff(take.samples[key]["t_host_s"]) >= 0), key


def client_status(gw: Gateway) -> list[dict]:
    return gw.status()["stations"]
