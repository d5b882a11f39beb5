"""Xsens exports: MVN's MVNX (XML) and the MT Manager / Xsens DOT text exports.

**MVNX** (MVN Analyze/Animate, ``<mvnx xmlns="http://www.xsens.com/mvn/mvnx">``): ``subject`` has ``frameRate``,
``sensors/sensor[@label]`` (Pelvis, T8, LeftForeArm, ...) and ``frames/frame``; the first frames are the
``identity``/``tpose``/``tpose-isb`` calibration frames, recorded data has ``type="normal"`` and ``time`` in ms.
Per frame, ``sensorOrientation`` holds 4 numbers per sensor (q0..q3, w first, sensor -> MVN global frame, Z up)
and ``sensorFreeAcceleration`` 3 per sensor (m/s², global frame, gravity removed). MVN no longer stores the raw
accelerometer, so the specific force the sensor measured is rebuilt as ``R_sᵀ (a_free + g ẑ)``.

**MT Manager text export** (MTi/MTw, one ``.txt`` per device, tab separated): ``//`` preamble lines (``DeviceId:``,
``Update Rate:``, ``Coordinate system: ENU``) then a header such as ``PacketCounter SampleTimeFine ... Acc_X Acc_Y
Acc_Z Gyr_X Gyr_Y Gyr_Z ... Quat_q0 Quat_q1 Quat_q2 Quat_q3``. ``Acc_*`` is the calibrated specific force in the
sensor frame (m/s²), ``Gyr_*`` rad/s, ``Quat_q0..3`` w first, sensor -> global. Time: ``SampleTimeFine`` (10 kHz
ticks, wraps at 2³²) when present, else ``PacketCounter`` at the update rate. The Xsens DOT CSV export
(``PacketCounter,SampleTimeFine,Quat_W,Quat_X,Quat_Y,Quat_Z,FreeAcc_X,FreeAcc_Y,FreeAcc_Z``) is read the same way,
free acceleration being turned back into specific force as for MVNX."""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from xml.parsers import expat
from pathlib import Path

import numpy as np

from engine import progress
from engine.errors import CourtsideError, MalformedFileError
from engine.imu_import.orientations import orientation_rows
from engine.imu_import.origin import Origin
from engine.imu_import.table import Table, read_table
from engine.imu_import.take import SensorStream
from engine.mocap import quaternions as quat
from engine.mocap.sensors import GRAVITY_MPS2
from engine.recording_limits import rate_problem

MVNX_NS = "http://www.xsens.com/mvn/mvnx"
# MVN sensor labels -> standard placements (MVN's hand/upper-arm/thigh sensors have no standard placement)
MVN_DEFAULT_MAP = {"Pelvis": "lower_back", "T8": "chest", "LeftForeArm": "left_forearm",
                   "RightForeArm": "right_forearm", "LeftLowerLeg": "left_shin", "RightLowerLeg": "right_shin",
                   "RightFoot": "right_foot"}
SAMPLE_TIME_FINE_HZ = 10_000.0
_WRAP_32 = 2.0**32
_UP_Z = np.array([0.0, 0.0, 1.0])


def specific_force_from_free(free_mps2: np.ndarray, q_wxyz: np.ndarray) -> np.ndarray:
    """Sensor-frame specific force (m/s²) from global free acceleration and sensor -> global quaternions
    (global Z up): ``R_sᵀ (a_free + g ẑ)``. NaN where the orientation is missing (NaN): there is no frame to
    rebuild it in (`quaternions.to_matrix` would take a NaN quaternion as the identity)."""
    q = np.asarray(q_wxyz, float)
    world = np.asarray(free_mps2, float) + GRAVITY_MPS2 * _UP_Z
    force = np.einsum("...ji,...j->...i", quat.to_matrix(q), world)
    return np.where(np.isfinite(q).all(axis=-1, keepdims=True), force, np.nan)


def _tag(name: str) -> str:
    return f"{{{MVNX_NS}}}{name}"


class _PrologEnd(Exception):
    """The first element was reached: the prolog (where a DOCTYPE would be) is over."""


def _refuse_declarations(path: Path) -> None:
    """Refuse a DOCTYPE (and so any entity declaration) before parsing: MVN never writes one, and entities
    let a 3 MB file expand, within the XML parser's own amplification limit, into gigabytes of numbers
    (issue 30). Only the prolog is read: expat is stopped at the first element, so this costs nothing."""
    scanner = expat.ParserCreate()

    def doctype(*_: object) -> None:
        raise MalformedFileError(path, scanner.CurrentLineNumber, "a DOCTYPE/entity declaration: not an MVNX export "
                                                                  "(MVN writes none)")

    def first_element(*_: object) -> None:
        raise _PrologEnd

    scanner.StartDoctypeDeclHandler = doctype
    scanner.StartElementHandler = first_element
    try:
        with open(path, "rb") as fh:
            while chunk := fh.read(64 * 1024):
                scanner.Parse(chunk, False)
    except _PrologEnd:
        return
    except expat.ExpatError as exc:
        raise MalformedFileError(path, exc.lineno, f"not well-formed MVNX XML ({expat.errors.messages[exc.code]})") \
            from None
    except OSError as exc:
        raise MalformedFileError(path, None, f"cannot read: {exc.strerror}") from None


def _numbers(path: Path, frame: ET.Element, child: str, n_sensors: int, per_sensor: int) -> np.ndarray:
    """The ``per_sensor`` numbers of each sensor in one frame's ``child`` element; a missing, empty or short one
    is refused naming the frame (MVN writes every sensor's values in every normal frame)."""
    count = n_sensors * per_sensor
    elem = frame.find(_tag(child))
    text = "" if elem is None or elem.text is None else elem.text
    try:
        values = np.array(text.split(), float)
    except ValueError:
        raise MalformedFileError(path, None, f"frame {frame.attrib.get('index')!r}: {child} holds a non-number") \
            from None
    if len(values) != count:
        raise MalformedFileError(path, None, f"frame {frame.attrib.get('index')!r}: {child} holds {len(values)} "
                                             f"numbers, expected {count} ({per_sensor} for each of the {n_sensors} "
                                             "sensors)")
    return values


def read_mvnx(path: str | Path, sensor_map: dict[str, str] | None = None) -> tuple[list[SensorStream], list[str]]:
    """Streams of the mapped MVN sensors (default ``MVN_DEFAULT_MAP``) and the labels left out. A sensor's
    missing orientations (`orientations.orientation_rows`) leave its rebuilt acceleration missing there too: free
    acceleration is in the global frame and cannot be turned into the sensor's without one."""
    path = Path(path)
    _refuse_declarations(path)
    mapping = sensor_map or MVN_DEFAULT_MAP
    labels: list[str] = []
    times, orient, free = [], [], []
    try:
        for _, elem in ET.iterparse(path, events=("end",)):
            tag = elem.tag.split("}", 1)[-1]
            if tag == "sensor" and "label" in elem.attrib:
                labels.append(elem.attrib["label"])
            elif tag == "frame":
                if elem.attrib.get("type", "normal") == "normal":
                    if not labels or "time" not in elem.attrib:
                        raise MalformedFileError(path, None, f"frame {elem.attrib.get('index')!r} lacks a time, or "
                                                             "comes before the sensor list")
                    times.append(_frame_time_ms(path, elem))
                    orient.append(_numbers(path, elem, "sensorOrientation", len(labels), 4))
                    free.append(_numbers(path, elem, "sensorFreeAcceleration", len(labels), 3))
                elem.clear()
    except ET.ParseError as exc:
        raise MalformedFileError(path, exc.position[0], f"not well-formed MVNX XML ({exc})") from None
    except OSError as exc:
        raise MalformedFileError(path, None, f"cannot read: {exc.strerror}") from None
    if not labels or not times:
        raise MalformedFileError(path, None, "no sensors or no normal frames: not an MVNX export with sensor data")
    n_s = len(labels)
    q = np.stack(orient).reshape(len(times), n_s, 4)
    a = np.stack(free).reshape(len(times), n_s, 3)
    t_s = np.array(times) * 1e-3
    origin = Origin(path)
    streams, ignored = [], []
    for k, label in enumerate(labels):
        if label not in mapping:
            ignored.append(label)
            continue
        qn = orientation_rows(q[:, k], origin, label)
        streams.append(SensorStream(label, mapping[label], t_s, specific_force_from_free(a[:, k], qn), qn, None,
                                    ("wxyz", True), origin))
    unknown = sorted(set(mapping) - set(labels))
    if sensor_map and unknown:
        raise CourtsideError(f"{path}: no MVN sensor(s) {unknown}; the file has {', '.join(labels)}")
    if not streams:
        raise CourtsideError(f"{path}: none of the sensors {labels} is mapped; give --sensor-map LABEL=PLACEMENT")
    return streams, ignored


def _frame_time_ms(path: Path, frame: ET.Element) -> float:
    try:
        return float(frame.attrib["time"])
    except ValueError:
        raise MalformedFileError(path, None, f"frame {frame.attrib.get('index')!r}: time "
                                             f"{frame.attrib['time'][:40]!r} is not a number") from None


def _preamble_entry(table: Table, key: str) -> tuple[int, str] | None:
    """(1-based line, value) of a ``// key: value`` preamble line, or None."""
    for i, line in enumerate(table.preamble):
        m = re.match(rf"^\s*//\s*{re.escape(key)}\s*:\s*(.*?)\s*$", line)
        if m:
            return i + 1, m.group(1)
    return None


def _preamble_value(table: Table, key: str) -> str | None:
    entry = _preamble_entry(table, key)
    return None if entry is None else entry[1]


def _update_rate_hz(table: Table) -> float | None:
    """The preamble's ``Update Rate: 100.0Hz`` (None when absent); anything that is not one number of Hz in the
    plausible range is refused naming the line (``fast`` and ``1.0.0Hz`` are not rates)."""
    entry = _preamble_entry(table, "Update Rate")
    if entry is None:
        return None
    line, text = entry
    m = re.fullmatch(r"([0-9]+(?:\.[0-9]*)?)\s*(?:Hz)?", text, flags=re.IGNORECASE)
    problem = rate_problem(float(m.group(1))) if m else None
    if m is None or problem:
        raise MalformedFileError(table.path, line, f"Update Rate {text!r} is not a sample rate"
                                                   f"{f' ({problem})' if problem else ''}; give --rate")
    return float(m.group(1))


def _time_s(table: Table, rate_hz: float | None) -> np.ndarray:
    if "SampleTimeFine" in table.header:
        ticks = table.get(["SampleTimeFine"])[:, 0]
        if np.all(np.isfinite(ticks)):
            wraps = np.cumsum(np.r_[0.0, np.diff(ticks) < -_WRAP_32 / 2])
            return (ticks + wraps * _WRAP_32) / SAMPLE_TIME_FINE_HZ
    rate = rate_hz or _update_rate_hz(table)
    if "PacketCounter" in table.header and rate:
        counter = table.get(["PacketCounter"])[:, 0]
        wraps = np.cumsum(np.r_[0.0, np.diff(counter) < -32768])
        return (counter + wraps * 65536.0) / rate
    raise MalformedFileError(table.path, table.header_line, "no usable time: SampleTimeFine is missing or NaN and "
                             "there is no PacketCounter with an update rate; give --rate")


def device_id(table: Table) -> str:
    """The device id from the preamble (``DeviceId: 00B42D4F``), else from the file name (``..._00B42D4F.txt``)."""
    found = _preamble_value(table, "DeviceId") or _preamble_value(table, "Device ID")
    if found:
        return found.strip()
    m = re.search(r"([0-9A-Fa-f]{8})(?:[_-]\d+)?$", table.path.stem)
    return m.group(1) if m else table.path.stem


def read_mt_text(paths: list[Path], sensor_map: dict[str, str] | None,
                 rate_hz: float | None = None) -> tuple[list[SensorStream], list[str]]:
    """Streams of MT Manager / Xsens DOT text exports (one file per device), mapped by device id (or file stem)."""
    if rate_hz is not None and rate_problem(rate_hz):
        raise CourtsideError(f"--rate {rate_problem(rate_hz)}")
    streams, ignored = [], []
    for path in progress.bar(paths, desc="reading devices", unit="file"):
        table = read_table(path)
        label = device_id(table)
        name = (sensor_map or {}).get(label) or (sensor_map or {}).get(path.stem)
        if name is None:
            ignored.append(label)
            continue
        t = _time_s(table, rate_hz)
        quat_cols = next((c for c in (["Quat_q0", "Quat_q1", "Quat_q2", "Quat_q3"], ["Quat_W", "Quat_X", "Quat_Y", "Quat_Z"])
                          if all(x in table.header for x in c)), None)
        q = orientation_rows(table.get(quat_cols), table.origin(), label) if quat_cols else None
        if all(c in table.header for c in ("Acc_X", "Acc_Y", "Acc_Z")):
            acc = table.get(["Acc_X", "Acc_Y", "Acc_Z"])
        elif all(c in table.header for c in ("FreeAcc_X", "FreeAcc_Y", "FreeAcc_Z")) and q is not None:
            acc = specific_force_from_free(table.get(["FreeAcc_X", "FreeAcc_Y", "FreeAcc_Z"]), q)
        else:
            raise MalformedFileError(path, table.header_line, "no Acc_X/Acc_Y/Acc_Z columns (nor FreeAcc_* with a "
                                     "quaternion): export the calibrated acceleration")
        gyro = table.get(["Gyr_X", "Gyr_Y", "Gyr_Z"]) if all(c in table.header for c in ("Gyr_X", "Gyr_Y", "Gyr_Z")) else None
        streams.append(SensorStream(label, name, t, acc, q, gyro, ("wxyz", True) if q is not None else None,
                                    table.origin()))
    if not streams:
        raise CourtsideError(f"no device is mapped to a sensor placement (devices: {', '.join(ignored)}); "
                             "give --sensor-map DEVICEID=PLACEMENT")
    return streams, ignored


def read_xsens(path: str | Path, sensor_map: dict[str, str] | None = None,
               rate_hz: float | None = None) -> tuple[list[SensorStream], list[str]]:
    """An ``.mvnx`` file, one MT/DOT text export, or a folder of them."""
    path = Path(path)
    if path.suffix.lower() == ".mvnx":
        return read_mvnx(path, sensor_map)
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in (".txt", ".csv"))
        mvnx = sorted(path.glob("*.mvnx"))
        if mvnx and not files:
            return read_mvnx(mvnx[0], sensor_map)
        if not files:
            raise MalformedFileError(path, None, "no .mvnx, .txt or .csv Xsens export in this folder")
        return read_mt_text(files, sensor_map, rate_hz)
    return read_mt_text([path], sensor_map, rate_hz)
