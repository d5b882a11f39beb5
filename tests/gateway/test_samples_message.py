"""One samples message (issue 13 "Shape"): what a client receives per batch and what the recorder writes are the
same message — same header fields, same arrays with the same dtypes — and the recorded samples equal, sample for
sample, what was streamed."""
from __future__ import annotations

import time

import numpy as np

from firmware_protocol.emulator import StationConfig
from gateway.client import GatewayClient
from gateway.daemon import Gateway
from firmware_protocol.emulator.stations import start_emulated_station
from gateway.recorder import read_recording


def test_streamed_and_recorded_samples_are_one_message(tmp_path):
    station = start_emulated_station(StationConfig(station_id=3, n_sensors=2, autostart=True))
    try:
        with Gateway([station.path], listen=("127.0.0.5", 0), record_dir=tmp_path) as gw, \
                GatewayClient(*gw.address) as client:
            streamed = []
            client.subscribe(["samples"])
            deadline = time.monotonic() + 15
            while not gw.list_stations()[0]["link"] == "streaming" and time.monotonic() < deadline:
                time.sleep(0.05)
            client.add_listener("samples", streamed.append)
            gw.handle_request("start_recording", {"take": "one"})
            time.sleep(1.5)
            gw.handle_request("stop_recording", {})
            time.sleep(0.3)
            client.remove_listener("samples", streamed.append)
    finally:
        station.stop()
    recorded = [m for m in read_recording(tmp_path / "one" / "take.csrec").messages if m.kind == "samples"]
    assert recorded and streamed
    live = streamed[0]
    assert set(live.header) == set(recorded[0].header)
    assert {k: v.dtype for k, v in live.arrays.items()} == {k: v.dtype for k, v in recorded[0].arrays.items()}
    # every recorded sample was streamed with identical values (the stream also has samples outside the take)
    for sensor in (0, 1):
        rec = np.concatenate([m["counter"] for m in recorded if m["sensor"] == sensor])
        rec_acc = np.concatenate([m["acc_g"] for m in recorded if m["sensor"] == sensor])
        live_by_counter = {int(c): a for m in streamed if m["sensor"] == sensor
                           for c, a in zip(m["counter"], m["acc_g"])}
        assert len(rec) > 50 and all(int(c) in live_by_counter for c in rec)
        np.testing.assert_array_equal(rec_acc, np.array([live_by_counter[int(c)] for c in rec]))
