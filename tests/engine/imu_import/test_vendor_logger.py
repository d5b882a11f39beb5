"""The x-IMU3 format as the vendor writes it: x-io's own `ximu3.DataLogger` records two emulated x-IMU3s (binary
mode, on ptys, opened by the vendor's library as hardware), and `courtside import-imu --format ximu3` reads that
recording back to the accelerations the devices sent (the fixtures in formats.py copy the logger's headings; this
checks them against the logger itself: folder names after its ping, Command.json, Temperature.csv beside)."""
from __future__ import annotations

import time

import numpy as np
import pytest

RATE_HZ = 100.0


def _signal(phase: float) -> np.ndarray:
    """20 s of a slow, smooth specific force (g) at RATE_HZ: linear interpolation between samples is exact to
    ~1e-4 g, so the imported grid can be checked against the sent samples."""
    t = np.arange(int(20 * RATE_HZ)) / RATE_HZ
    return np.column_stack([0.4 * np.sin(2 * np.pi * 0.5 * t + phase), 0.2 * np.cos(2 * np.pi * 0.3 * t),
                            0.9 + 0.05 * np.sin(2 * np.pi * 0.2 * t + phase)])


def test_import_reads_what_the_vendors_data_logger_wrote(tmp_path):
    ximu3 = pytest.importorskip("ximu3")
    from engine.imu_import.cli import main
    from firmware_protocol.emulator.ximu3_device import Ximu3Emulator

    devices = [Ximu3Emulator(name=name, serial=serial, acc_g=_signal(phase), drift_ppm=drift, seed=k).start()
               for k, (name, serial, phase, drift) in enumerate([("Left Shin", "0000A001", 0.0, 40.0),
                                                                 ("Lower Back", "0000A002", 1.0, -25.0)])]
    connections = []
    try:
        for d in devices:
            connection = ximu3.Connection(ximu3.SerialConnectionConfig(d.path, 115200, False))
            connection.open()
            connections.append(connection)
        logger = ximu3.DataLogger(str(tmp_path), "session", connections)
        time.sleep(3.0)
        del logger  # stops logging; the logger then renames each folder after its device's ping answer
    finally:
        for c in connections:
            c.close()
        for d in devices:
            d.stop()
    folders = sorted(p.name for p in (tmp_path / "session").iterdir())
    assert folders == ["Left Shin 0000A001 (USB)", "Lower Back 0000A002 (USB)"]
    assert main([str(tmp_path / "session"), "--format", "ximu3", "-o", str(tmp_path / "take.npz")]) == 0
    with np.load(tmp_path / "take.npz", allow_pickle=False) as take:
        names = [str(n) for n in take["sensor_names"]]
        acc, t_s = take["acc_g"], take["t_s"]
        assert take["quat_wxyz"].shape == acc.shape[:2] + (4,)  # the AHRS messages the devices sent between
    assert names == ["left_shin", "lower_back"]  # devices named after placements map themselves
    assert len(t_s) > 2.0 * RATE_HZ
    for k, (device, name) in enumerate(zip(devices, ["Left Shin 0000A001 (USB)", "Lower Back 0000A002 (USB)"])):
        logged = np.loadtxt(tmp_path / "session" / name / "Inertial.csv", delimiter=",", skiprows=1, ndmin=2)
        sent_us = np.array(device.truth.device_us, float)
        sent = np.array(device.truth.acc_g)
        # each device's stream starts at its first logged sample (the import's alignment rule)
        expected = np.column_stack([np.interp(logged[0, 0] + t_s * 1e6, sent_us, sent[:, a]) for a in range(3)])
        assert np.abs(acc[:, k] - expected).max() < 2e-4, np.abs(acc[:, k] - expected).max()
