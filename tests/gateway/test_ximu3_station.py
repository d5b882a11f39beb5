"""An x-IMU3 as a gateway station: the vendor's `ximu3` library opens an emulated x-IMU3 on a pty (ASCII serial
protocol, its own drifting microsecond clock, lost samples), and the gateway aligns, counts, records and serves
its samples like those of the project's own stations."""
from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip("ximu3")

from gateway.client import GatewayClient  # noqa: E402
from gateway.daemon import Gateway  # noqa: E402
from gateway.recorder import load_take, realign_take  # noqa: E402
from gateway.vendors.ximu3_emulator import Ximu3Emulator  # noqa: E402


def _wait(predicate, timeout_s: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return False


def test_ximu3_streams_records_and_aligns(tmp_path):
    with Ximu3Emulator(serial="65577B49", rate_hz=100.0, drift_ppm=80.0, loss=0.02, seed=1) as emu, \
            Gateway([f"ximu3:{emu.path}"], listen=("127.0.0.1", 0), record_dir=tmp_path) as gw:
        assert _wait(lambda: gw.list_stations()[0]["station"] == "ximu3-65577B49")
        gw.recorder.start("x")
        time.sleep(6.0)
        gw.recorder.stop()
        with GatewayClient(*gw.address).connect() as client:  # what a console sees
            stations = client.list_stations()
        status = gw.list_stations()[0]
    assert stations[0]["station"] == "ximu3-65577B49" and stations[0]["device"] == "x-IMU3"
    assert status["device_clock"] is True and status["link"] in ("streaming", "stopped")
    sensor = status["sensors"][0]
    assert sensor["nominal_hz"] == pytest.approx(100.0, rel=1e-3)
    assert sensor["received"] > 500 and 0 < sensor["lost"] < 0.06 * sensor["received"]
    assert emu.commands[0] == {"ping": None}
    take = load_take(tmp_path / "x")
    cols = take.samples[("ximu3-65577B49", 0)]
    truth_host = dict(zip(np.array(emu.truth.device_us) % (1 << 32), emu.truth.host_s))
    truth_acc = dict(zip(np.array(emu.truth.device_us) % (1 << 32), emu.truth.acc_g))
    assert all(int(r) in truth_host for r in cols["raw_ticks"])  # every recorded sample is a sent one
    np.testing.assert_allclose(cols["acc_g"], [truth_acc[int(r)] for r in cols["raw_ticks"]], atol=1e-6)
    # clock: online estimate and the offline re-fit from the recorded clock points, against the true latch times
    host = np.array([truth_host[int(r)] for r in cols["raw_ticks"]])
    settled = host > host[0] + 2.0
    online = np.abs(cols["t_host_s"] - host)[settled]
    offline = np.abs(realign_take(take)[("ximu3-65577B49", 0)] - host)
    assert np.percentile(online, 99) < 2e-3 and np.percentile(offline, 99) < 2e-3, \
        (np.percentile(online, 99), np.percentile(offline, 99))


def test_a_port_that_is_not_an_ximu3_is_reported(tmp_path):
    import os
    import pty
    import tty

    master, slave = pty.openpty()
    tty.setraw(slave)
    with Gateway([f"ximu3:{os.ttyname(slave)}"], listen=("127.0.0.1", 0), record_dir=tmp_path) as gw:
        assert _wait(lambda: gw.list_stations()[0]["link_error"] is not None, 15.0)
        assert "no answer to ping" in gw.list_stations()[0]["link_error"]
    os.close(master)
    os.close(slave)
