"""A generic CSV/TSV of IMU readings with a user-given column map.

Per sensor: three acceleration columns (sensor frame, unit detected or stated), optionally four quaternion
columns in file order (w-first or w-last detected, see ``engine.imu_import.detect``) and three gyro columns.
Time: a column (``s``, ``ms`` or ``us``) or a constant rate. Delimiter: tab, comma or semicolon, sniffed from the
header row. Columns are named as in the header or by 0-based index."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.errors import CourtsideError, MalformedFileError
from engine.imu_import.table import Table, read_table
from engine.imu_import.take import SensorStream
from engine.recording_limits import rate_problem

TIME_UNITS_S = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
GYRO_UNITS_RPS = {"rad/s": 1.0, "deg/s": np.pi / 180.0}


def read_generic_csv(path: str | Path, acc: dict[str, list[str]], quat: dict[str, list[str]] | None = None,
                     gyro: dict[str, list[str]] | None = None, time_column: str | None = None,
                     time_unit: str = "s", rate_hz: float | None = None, gyro_unit: str = "rad/s",
                     delimiter: str | None = None) -> list[SensorStream]:
    """Streams named by the keys of ``acc`` (standard placement names); see the module docstring."""
    quat, gyro = quat or {}, gyro or {}
    for kind, mapping, width in (("acceleration", acc, 3), ("quaternion", quat, 4), ("gyro", gyro, 3)):
        for name, cols in mapping.items():
            if len(cols) != width:
                raise CourtsideError(f"{kind} of sensor {name!r} needs {width} columns, got {len(cols)}: {cols}")
            if kind != "acceleration" and name not in acc:
                raise CourtsideError(f"{kind} columns given for {name!r}, which has no acceleration columns")
    if (time_column is None) == (rate_hz is None):
        raise CourtsideError("give exactly one of a time column (--time) and a sample rate (--rate)")
    if time_unit not in TIME_UNITS_S or gyro_unit not in GYRO_UNITS_RPS:
        raise CourtsideError(f"time unit must be one of {list(TIME_UNITS_S)}, gyro unit one of {list(GYRO_UNITS_RPS)}")
    if rate_hz is not None and rate_problem(rate_hz):
        raise CourtsideError(f"--rate {rate_problem(rate_hz)}")
    table = read_table(path, delimiter)
    _check_columns_used_once(table, {"acceleration": acc, "quaternion": quat, "gyro": gyro})
    n = len(table.values)
    t = (table.get([time_column])[:, 0] * TIME_UNITS_S[time_unit] if time_column is not None
         else np.arange(n) / float(rate_hz))
    return [SensorStream(label=name, name=name, t_s=t, acc=table.get(cols),
                         quat_file=table.get(quat[name]) if name in quat else None,
                         gyro_rps=table.get(gyro[name]) * GYRO_UNITS_RPS[gyro_unit] if name in gyro else None,
                         origin=table.origin())
            for name, cols in acc.items()]


def _check_columns_used_once(table: Table, mappings: dict[str, dict[str, list[str]]]) -> None:
    """Refuse a column mapped twice (two placements on the same columns would import one sensor as two; one
    column as two axes is a typo), naming both uses. Names and indexes are resolved first, so ``ax`` and ``1``
    for the same column are caught."""
    used: dict[int, str] = {}
    for kind, mapping in mappings.items():
        for name, cols in mapping.items():
            for col in cols:
                index = table.column(col)
                what = f"{kind} of {name!r}"
                if index in used:
                    raise MalformedFileError(table.path, table.header_line,
                                             f"column {table.header[index]!r} is mapped twice: {used[index]} and "
                                             f"{what}")
                used[index] = what
