"""Raw per-sensor streams from a device file -> one take on a common time grid, in the synthesis-input format.

The output ``.npz`` is exactly what ``engine.graph.inputs.load_take`` reads (``courtside synthesize`` and
``courtside reconstruct``): ``acc_g`` (T, S, 3) g in each sensor's own frame, ``fps``, ``sensor_names`` (S,)
standard placement names. It adds ``t_s`` (T,), ``source_labels`` (S,) (the device's own name for each sensor),
``gyro_rps`` (T, S, 3) rad/s and ``quat_wxyz`` (T, S, 4) (sensor -> device world) when the file has them, and
``import_report`` (JSON text: format, units and quaternion layout detected per sensor). No pickled objects, so
``numpy.load(allow_pickle=False)`` reads it.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from engine.atomic_write import atomic_write
from engine.errors import CourtsideError
from engine.imu_import.detect import detect_quat_layout, detect_units, layout_scores, to_wxyz
from engine.imu_import.origin import Origin, stream_error
from engine.imu_import.orientations import orientation_rows
from engine.imu_import.samples import check_acceleration_range, missing_rows
from engine.imu_import.timing import (bridge, bridge_quaternions, check_gaps, check_times, common_grid,
                                     neighbours_s, sample_rate)
from engine.mocap import STANDARD_SENSORS
from engine.mocap import quaternions as quat
from engine.recording_limits import MAX_GAP_S

_RATE_ROUNDING = 1e-3  # rates are rounded to this many Hz when they agree across sensors


@dataclass
class SensorStream:
    """One sensor as read from a file, before unit/layout detection: times (s, any origin), acceleration in the
    file's unit, quaternion columns in file order (or None), gyro in rad/s (or None), and where the samples came
    from (for messages naming the file and line; None for streams built in code)."""

    label: str
    name: str
    t_s: np.ndarray
    acc: np.ndarray
    quat_file: np.ndarray | None = None
    gyro_rps: np.ndarray | None = None
    quat_layout: tuple[str, bool] | None = None  # known from the format: (order, sensor_to_world)
    origin: Origin | None = None


@dataclass
class ImportedTake:
    """A take on one time grid (see the module docstring for the arrays)."""

    fps: float
    t_s: np.ndarray
    acc_g: np.ndarray
    sensor_names: list[str]
    source_labels: list[str]
    gyro_rps: np.ndarray | None = None
    quat_wxyz: np.ndarray | None = None
    report: dict[str, Any] = field(default_factory=dict)

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        arrays: dict[str, Any] = dict(acc_g=self.acc_g, fps=np.float64(self.fps), t_s=self.t_s,
                                      sensor_names=np.array(self.sensor_names), source_labels=np.array(self.source_labels),
                                      import_report=np.array(json.dumps(self.report)))
        if self.gyro_rps is not None:
            arrays["gyro_rps"] = self.gyro_rps
        if self.quat_wxyz is not None:
            arrays["quat_wxyz"] = self.quat_wxyz
        # to a file object: np.savez would append ".npz" to any other suffix
        return atomic_write(path, lambda fh: np.savez_compressed(fh, **arrays))


def check_names(streams: list[SensorStream]) -> None:
    """Every stream must map to a distinct standard placement name (what the graph's virtual sensors are)."""
    seen: dict[str, str] = {}
    for s in streams:
        if s.name not in STANDARD_SENSORS:
            raise CourtsideError(f"sensor {s.label!r} is mapped to {s.name!r}, which is not a standard sensor "
                                 f"placement; known: {', '.join(STANDARD_SENSORS)}")
        if s.name in seen:
            raise CourtsideError(f"sensors {seen[s.name]!r} and {s.label!r} are both mapped to {s.name!r}")
        seen[s.name] = s.label


@dataclass
class _Cleaned:
    """One stream after the sample rules: usable times (strictly increasing), acceleration in g with missing
    rows NaN, orientation (file order) and gyro with missing rows NaN, and its median rate."""

    stream: SensorStream
    t_s: np.ndarray
    acc_g: np.ndarray
    quat: np.ndarray | None
    gyro_rps: np.ndarray | None
    rate_hz: float


def _clean(s: SensorStream, units: str) -> tuple[_Cleaned, dict[str, Any]]:
    """`SensorStream` -> `_Cleaned` by the rules of `timing`, `samples` and `orientations` (a refusal names the
    file and line), with the units detected; plus the stream's report entry."""
    t = np.asarray(s.t_s, float)
    check_times(t, s.origin, s.label)
    distinct = np.r_[True, np.diff(t) > 0]  # equal times: the first sample is kept
    origin = None if s.origin is None else s.origin.subset(np.flatnonzero(distinct))
    t, acc = t[distinct], np.asarray(s.acc, float)[distinct]
    usable = ~missing_rows(acc, origin, s.label, "acceleration")
    if usable.sum() < 3:
        raise stream_error(origin, s.label, None, f"fewer than 3 usable samples ({int(usable.sum())})")
    rate = sample_rate(t[usable], origin, s.label)
    check_gaps(t[usable], None if origin is None else origin.subset(np.flatnonzero(usable)), s.label)
    with np.errstate(over="ignore", invalid="ignore"):  # a 1e300 reading is refused just below, not warned about
        u = detect_units(acc[usable], rate, units, what=f"sensor {s.label!r}")
    acc_g = acc * u.to_g
    check_acceleration_range(acc_g, origin, s.label)
    q = None if s.quat_file is None else orientation_rows(np.asarray(s.quat_file, float)[distinct], origin, s.label)
    gyro = None
    if s.gyro_rps is not None:
        gyro = np.asarray(s.gyro_rps, float)[distinct]
        missing_rows(gyro, origin, s.label, "gyro")
    report = {"name": s.name, "rate_hz": round(rate, 3), "units": u.units, "units_detected": u.detected,
              "rest_norm": round(u.rest_norm, 4), "still_fraction": round(u.still_fraction, 3),
              "samples": int(usable.sum())}
    return _Cleaned(s, t, acc_g, q, gyro, rate), report


def _to_wxyz_sensor_to_world(cleaned: list[_Cleaned], quat_order: str, report: dict[str, Any]) -> None:
    """Orientations in place as (w, x, y, z) sensor -> world: the format's known layout, else one layout for the
    whole file detected on all its quaternion sensors together (`detect`)."""
    unknown = [c for c in cleaned if c.quat is not None and c.stream.quat_layout is None]
    if unknown:
        layout = detect_quat_layout([layout_scores(c.quat, c.acc_g, c.rate_hz) for c in unknown], quat_order)
        report["quaternions"] = {"order": layout.order, "sensor_to_world": layout.sensor_to_world,
                                 "score": round(layout.concentration, 4), "runner_up": round(layout.runner_up, 4),
                                 "world_up": np.round(layout.world_up, 3).tolist()}
    for c in cleaned:
        if c.quat is not None:
            order_name, s2w = c.stream.quat_layout or (layout.order, layout.sensor_to_world)
            q = to_wxyz(c.quat, order_name)
            c.quat = q if s2w else quat.conjugate(q)


def assemble(streams: list[SensorStream], fmt: str, units: str = "auto", quat_order: str = "auto",
             extra_report: dict[str, Any] | None = None) -> ImportedTake:
    """Check and clean each stream (units detected, converted to g; orientations as (w, x, y, z) sensor ->
    world) and put every sensor on one grid at the slowest sensor's median rate over the span all sensors cover.

    Orientation is written when any sensor has one; a sensor without one has NaN there (named in the report's
    ``no_orientation``), so one device missing its orientation does not take the others' away. Gyro is written
    only when every sensor has one."""
    if not streams:
        raise CourtsideError("no sensors to import (check the sensor map)")
    check_names(streams)
    report: dict[str, Any] = {"format": fmt, "sensors": {}, **(extra_report or {})}
    cleaned = []
    for s in streams:
        c, report["sensors"][s.label] = _clean(s, units)
        cleaned.append(c)
    _to_wxyz_sensor_to_world(cleaned, quat_order, report)
    rate = round(min(c.rate_hz for c in cleaned) / _RATE_ROUNDING) * _RATE_ROUNDING
    usable_t = [c.t_s[np.isfinite(c.acc_g).all(axis=1)] for c in cleaned]
    grid = common_grid([(float(t[0]), float(t[-1])) for t in usable_t], rate, max(len(c.t_s) for c in cleaned))
    acc = np.stack([bridge(grid, c.t_s, c.acc_g, MAX_GAP_S) for c in cleaned], axis=1)  # gaps checked: finite
    quats = None
    if any(c.quat is not None for c in cleaned):
        quats = np.stack([bridge_quaternions(grid, c.t_s, c.quat, neighbours_s(c.t_s)) if c.quat is not None
                          else np.full((len(grid), 4), np.nan) for c in cleaned], axis=1)
        report["no_orientation"] = [c.stream.label for c in cleaned if c.quat is None]
    gyro = (np.stack([bridge(grid, c.t_s, c.gyro_rps, neighbours_s(c.t_s)) for c in cleaned], axis=1)
            if all(c.gyro_rps is not None for c in cleaned) else None)
    report.update(fps=rate, samples=int(len(grid)), duration_s=round(float(grid[-1] - grid[0]), 4))
    return ImportedTake(rate, grid - grid[0], acc, [c.stream.name for c in cleaned],
                        [c.stream.label for c in cleaned], gyro, quats, report)
