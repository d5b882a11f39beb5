"""x-IMU3 data-logger recordings (x-io Technologies: x-IMU3 GUI "Data Logger" or the ximu3 API's DataLogger).

The logger writes one folder per recording and inside it one folder per connected device, named
``"<device name> <serial number> (<interface>)"`` once the device answered the logger's ping. Each device folder
holds one CSV per message type, written by the x-IMU3 API exactly as:

* ``Inertial.csv``: ``Timestamp (us),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),
  Accelerometer X (g),Accelerometer Y (g),Accelerometer Z (g)``
* ``Quaternion.csv``: ``Timestamp (us),W,X,Y,Z`` (AHRS output, sensor -> Earth, w first)

(plus Magnetometer.csv, Battery.csv, Command.json ... which are not needed here). Timestamps are each device's
own microsecond clock, so streams are put on a common time axis by their first logged sample: the logger opens
all devices at the same host moment (within one sample period; a cross-device sync tap or the x-IMU3
synchronisation input would be needed for better)."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from engine import progress
from engine.errors import CourtsideError, MalformedFileError
from engine.imu_import.orientations import orientation_rows
from engine.imu_import.table import read_table
from engine.imu_import.take import SensorStream
from engine.imu_import.timing import bridge_quaternions, check_times, neighbours_s
from engine.mocap import STANDARD_SENSORS

INERTIAL = "Inertial.csv"
QUATERNION = "Quaternion.csv"
INERTIAL_COLUMNS = ["Timestamp (us)", "Gyroscope X (deg/s)", "Gyroscope Y (deg/s)", "Gyroscope Z (deg/s)",
                    "Accelerometer X (g)", "Accelerometer Y (g)", "Accelerometer Z (g)"]
QUATERNION_COLUMNS = ["Timestamp (us)", "W", "X", "Y", "Z"]
_FOLDER = re.compile(r"^(?P<name>.+?) (?P<serial>[0-9A-Fa-f]{8}) \((?P<interface>[^)]*)\)$")


def device_folders(path: str | Path) -> list[Path]:
    """The device folders of a recording: ``path`` is the recording folder, one device folder, or an
    ``Inertial.csv``. A recording folder's device folders are those holding a CSV and those named as the logger
    names devices (``"<name> <serial> (<interface>)"``), so that a mapped device that logged no inertial data is
    reported rather than silently missing."""
    path = Path(path)
    if path.is_file():
        if path.name != INERTIAL:
            raise MalformedFileError(path, None, f"an x-IMU3 recording is a folder (or its {INERTIAL})")
        return [path.parent]
    if (path / INERTIAL).is_file():
        return [path]
    found = sorted(p for p in path.iterdir() if p.is_dir() and (_FOLDER.match(p.name) or any(p.glob("*.csv")))) \
        if path.is_dir() else []
    if not any((p / INERTIAL).is_file() for p in found):
        raise MalformedFileError(path, None, f"no x-IMU3 device folder with an {INERTIAL} in it")
    return found


def default_name(folder: Path) -> str | None:
    """Standard placement named by the device name (e.g. a device renamed "Left Forearm" or "left_forearm")."""
    m = _FOLDER.match(folder.name)
    device = (m.group("name") if m else folder.name).strip().lower().replace("-", "_").replace(" ", "_")
    return device if device in STANDARD_SENSORS else None


def _labels(folder: Path) -> set[str]:
    m = _FOLDER.match(folder.name)
    return {folder.name} | ({m.group("name"), m.group("serial")} if m else set())


def read_ximu3(path: str | Path, sensor_map: dict[str, str] | None = None) -> tuple[list[SensorStream], list[str]]:
    """Streams of the mapped devices (``sensor_map``: folder name, device name or serial -> placement name;
    default: devices named after a placement) and the labels of the devices left out. A mapped device without
    ``Inertial.csv`` is refused; one without ``Quaternion.csv`` has no orientation (NaN in the take, the other
    devices keep theirs)."""
    streams, ignored = [], []
    for folder in progress.bar(device_folders(path), desc="reading devices", unit="device"):
        name = next((sensor_map[k] for k in _labels(folder) if sensor_map and k in sensor_map), None)
        name = name or default_name(folder)
        if name is None:
            ignored.append(folder.name)
            continue
        if not (folder / INERTIAL).is_file():
            raise MalformedFileError(folder, None, f"mapped to {name!r} but holds no {INERTIAL}: the device logged "
                                                   "no inertial data (leave it out of --sensor-map)")
        inertial = read_table(folder / INERTIAL, ",")
        _require(inertial.header, INERTIAL_COLUMNS, folder / INERTIAL)
        t_us = inertial.get(INERTIAL_COLUMNS[:1])[:, 0]
        gyro = np.radians(inertial.get(INERTIAL_COLUMNS[1:4]))
        acc = inertial.get(INERTIAL_COLUMNS[4:7])
        quat = _orientation_at(folder, t_us) if (folder / QUATERNION).is_file() else None
        t_s = (t_us - t_us[0]) * 1e-6
        layout = ("wxyz", True) if quat is not None else None
        streams.append(SensorStream(folder.name, name, t_s, acc, quat, gyro, layout, inertial.origin()))
    if not streams:
        raise CourtsideError(f"{path}: no device is mapped to a sensor placement (devices: "
                             f"{', '.join(ignored)}); give --sensor-map DEVICE=PLACEMENT")
    return streams, ignored


def _orientation_at(folder: Path, t_us: np.ndarray) -> np.ndarray:
    """The device's ``Quaternion.csv`` (its own, usually slower, message rate) at the ``Inertial.csv`` times
    ``t_us``: NaN where it has no orientation (interpolated between neighbouring Quaternion.csv rows only).
    Refused when it has no rows or one, a clock reset, a bad quaternion (`orientations`), or no time in common
    with the inertial data (another clock)."""
    table = read_table(folder / QUATERNION, ",")
    _require(table.header, QUATERNION_COLUMNS, folder / QUATERNION)
    tq_us = table.get(QUATERNION_COLUMNS[:1])[:, 0]
    check_times(tq_us * 1e-6, table.origin(), folder.name)
    q = bridge_quaternions(np.asarray(t_us, float) * 1e-6, tq_us * 1e-6,
                           orientation_rows(table.get(QUATERNION_COLUMNS[1:]), table.origin(), folder.name),
                           neighbours_s(tq_us * 1e-6) if len(tq_us) > 1 else 0.0)  # one row: refused below
    if len(tq_us) < 2 or not np.isfinite(q).any():
        raise MalformedFileError(folder / QUATERNION, None, f"its {len(tq_us)} orientation row(s) at {tq_us[0]:.0f}.."
                                                            f"{tq_us[-1]:.0f} us do not cover {INERTIAL}'s "
                                                            f"{np.nanmin(t_us):.0f}..{np.nanmax(t_us):.0f} us (too few "
                                                            "rows, or another clock)")
    return q


def _require(header: list[str], columns: list[str], path: Path) -> None:
    missing = [c for c in columns if c not in header]
    if missing:
        raise MalformedFileError(path, 1, f"missing column(s) {missing}; this is not an x-IMU3 {path.name}")
