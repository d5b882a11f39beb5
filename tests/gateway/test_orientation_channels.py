"""Orientation and angular rate from a protocol-v2 station through the whole gateway: reader -> recording ->
TCP stream -> client, and every export (npz keys, CSV columns, XDF stream read back by pyxdf), checked against
what the emulated sensors really were (still sensors: a known pose, zero rate)."""
from __future__ import annotations

import csv
import threading
import time

import numpy as np
import pytest

from engine.mocap.orientation import to_device_earth
from gateway.client import GatewayClient
from gateway.daemon import Gateway
from gateway.recorder import export_csv, export_npz, load_take

HALF = np.sqrt(0.5)


def _same_rotation(got: np.ndarray, want: np.ndarray, atol: float) -> None:
    dots = np.abs(np.asarray(got, float) @ np.asarray(want, float))
    assert np.all(dots > 1.0 - atol), dots.min()


def test_orientation_station_reaches_recording_client_and_exports(tmp_path):
    # emu:// stations are still: sensor i lies with the identity pose (sensor Y up in the world), so its filter
    # reports the Z-up turn of the identity and its gyro reads zero
    want_q = to_device_earth(np.array([1.0, 0.0, 0.0, 0.0]))
    got: list = []
    done = threading.Event()

    def listen(message) -> None:
        got.append(message)
        if len(got) > 60:
            done.set()

    with Gateway(["emu://ori1?sensors=2&rate=100&seed=4&orientation=1&station-id=1",
                  "emu://acc2?sensors=1&rate=100&seed=5&station-id=2"],
                 listen=("127.0.0.1", 0), record_dir=tmp_path) as gw:
        time.sleep(0.3)
        gw.recorder.start("take1")
        with GatewayClient(*gw.address).connect() as client:
            client.add_listener("samples", listen)
            client.subscribe(["samples"])
            assert done.wait(20.0)
        time.sleep(1.0)
        gw.recorder.stop()
        channels = {s["station"]: [x["channels"] for x in s["sensors"]] for s in gw.list_stations()}
    assert channels == {"st1": [["acc", "orientation", "gyro"]] * 2, "st2": [["acc"]]}  # from each HELLO
    assert {m["station"] for m in got} == {"st1", "st2"}
    for m in got:  # the client sees the channels exactly when the station streams them
        assert ("quat_wxyz" in m.arrays) == (m["station"] == "st1") == ("gyro_rps" in m.arrays), m.header
        if "quat_wxyz" in m.arrays:
            _same_rotation(m["quat_wxyz"], want_q, 1e-7)
            assert not m["gyro_rps"].any()

    take = load_take(tmp_path / "take1")
    assert set(take.samples) >= {("st1", 0), ("st1", 1)}
    for (station, sensor), cols in take.samples.items():
        assert ("quat_wxyz" in cols) == (station == "st1")
        if station == "st1":
            assert cols["quat_wxyz"].shape == (len(cols["acc_g"]), 4) and len(cols["acc_g"]) > 50
            _same_rotation(cols["quat_wxyz"], want_q, 1e-7)

    npz = np.load(export_npz(tmp_path / "take1", tmp_path / "take1.npz"))
    assert "st1/0/quat_wxyz" in npz.files and "st1/1/gyro_rps" in npz.files
    assert not any(k.startswith("st2/") and k.endswith(("quat_wxyz", "gyro_rps")) for k in npz.files)
    np.testing.assert_array_equal(npz["st1/0/quat_wxyz"], take.samples[("st1", 0)]["quat_wxyz"])

    files = {p.name: p for p in export_csv(tmp_path / "take1", tmp_path / "csv")}
    with open(files["st1_0.csv"]) as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    assert [c for c in header if c.startswith(("quat", "gyro"))] == \
        ["quat_wxyz_w", "quat_wxyz_x", "quat_wxyz_y", "quat_wxyz_z", "gyro_rps_x", "gyro_rps_y", "gyro_rps_z"]
    first = np.array(rows[1], float)
    _same_rotation(first[header.index("quat_wxyz_w"):header.index("quat_wxyz_w") + 4][None], want_q, 1e-7)


def test_xdf_has_an_orientation_stream(tmp_path):
    pyxdf = pytest.importorskip("pyxdf")
    pytest.importorskip("pylsl")
    from gateway.xdf import export_xdf

    with Gateway(["emu://ori1?sensors=2&rate=100&seed=4&orientation=1"], listen=("127.0.0.1", 0),
                 record_dir=tmp_path) as gw:
        time.sleep(0.3)
        gw.recorder.start("take1")
        time.sleep(1.0)
        gw.recorder.stop()
    streams, _ = pyxdf.load_xdf(str(export_xdf(tmp_path / "take1", tmp_path / "t.xdf")), synchronize_clocks=False,
                                dejitter_timestamps=False)
    by_type = {s["info"]["type"][0]: s for s in streams}
    assert set(by_type) == {"Accelerometer", "Orientation"}
    ori = by_type["Orientation"]
    labels = [c["label"][0] for c in ori["info"]["desc"][0]["channels"][0]["channel"]]
    assert labels == ["sensor", "quat_w", "quat_x", "quat_y", "quat_z", "gyro_x_rps", "gyro_y_rps", "gyro_z_rps"]
    assert len(ori["time_stamps"]) == len(by_type["Accelerometer"]["time_stamps"]) > 100
    _same_rotation(ori["time_series"][:, 1:5], to_device_earth(np.array([1.0, 0, 0, 0])), 1e-6)
    assert not ori["time_series"][:, 5:].any()
