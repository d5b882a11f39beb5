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

from engine.errors import CourtsideError
from engine.mocap import STANDARD_SENSORS
from engine.mocap import quaternions as quat
from engine.imu_import.detect import detect_quat_layout, detect_units, layout_scores, to_wxyz

_RATE_ROUNDING = 1e-3  # rates are rounded to this many Hz when they agree across sensors


@dataclass
class SensorStream:
    """One sensor as read from a file, before unit/layout detection: times (s, any origin), acceleration in the
    file's unit, quaternion columns in file order (or None), gyro in rad/s (or None)."""

    label: str
    name: str
    t_s: np.ndarray
    acc: np.ndarray
    quat_file: np.ndarray | None = None
    gyro_rps: np.ndarray | None = None
    quat_layout: tuple[str, bool] | None = None  # known from the format: (order, sensor_to_world)


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
        try:
            with open(path, "wb") as fh:  # np.savez would append ".npz" to any other suffix
                np.savez_compressed(fh, **arrays)
        except OSError as exc:
            raise CourtsideError(f"{path}: cannot write the take ({exc.strerror or exc})") from None
        return path


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


def _rate(t: np.ndarray) -> float:
    dt = np.diff(t)
    dt = dt[dt > 0]
    if not len(dt):
        raise CourtsideError("fewer than two distinct timestamps")
    return float(1.0 / np.median(dt))


def _interp(t_out: np.ndarray, t: np.ndarray, values: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(t_out, t, values[:, k]) for k in range(values.shape[1])], axis=1)


def _interp_quat(t_out: np.ndarray, t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Normalised linear interpolation after making consecutive quaternions share a hemisphere."""
    q = q.copy()
    flip = np.cumprod(np.where(np.sum(q[1:] * q[:-1], axis=1) < 0, -1.0, 1.0))
    q[1:] *= flip[:, None]
    return quat.normalize(_interp(t_out, t, q))


def assemble(streams: list[SensorStream], fmt: str, units: str = "auto", quat_order: str = "auto",
             extra_report: dict[str, Any] | None = None) -> ImportedTake:
    """Detect units and quaternion layout per sensor, convert to g and (w, x, y, z) sensor -> world, and put
    every sensor on one grid at the slowest sensor's median rate over the span all sensors cover."""
    if not streams:
        raise CourtsideError("no sensors to import (check the sensor map)")
    check_names(streams)
    report: dict[str, Any] = {"format": fmt, "sensors": {}, **(extra_report or {})}
    cleaned = []
    for s in streams:
        order = np.argsort(s.t_s, kind="stable")
        t = np.asarray(s.t_s, float)[order]
        keep = np.r_[True, np.diff(t) > 0] & np.all(np.isfinite(s.acc[order]), axis=1)
        if keep.sum() < 3:
            raise CourtsideError(f"sensor {s.label!r}: fewer than 3 usable samples")
        rate = _rate(t[keep])
        u = detect_units(np.asarray(s.acc, float)[order][keep], rate, units, what=f"sensor {s.label!r}")
        report["sensors"][s.label] = {"name": s.name, "rate_hz": round(rate, 3), "units": u.units,
                                      "units_detected": u.detected, "rest_norm": round(u.rest_norm, 4),
                                      "still_fraction": round(u.still_fraction, 3), "samples": int(keep.sum())}
        q = None if s.quat_file is None else np.asarray(s.quat_file, float)[order][keep]
        gyro = None if s.gyro_rps is None else np.asarray(s.gyro_rps, float)[order][keep]
        cleaned.append([s, t[keep], np.asarray(s.acc, float)[order][keep] * u.to_g, q, gyro, rate])
    unknown = [c for c in cleaned if c[3] is not None and c[0].quat_layout is None]
    if unknown:  # one layout for the whole file, detected on all its quaternion sensors together
        layout = detect_quat_layout([layout_scores(c[3], c[2], c[5], f"sensor {c[0].label!r} quaternion")
                                     for c in unknown], quat_order)
        report["quaternions"] = {"order": layout.order, "sensor_to_world": layout.sensor_to_world,
                                 "score": round(layout.concentration, 4), "runner_up": round(layout.runner_up, 4),
                                 "world_up": np.round(layout.world_up, 3).tolist()}
    for c in cleaned:
        if c[3] is not None:
            order_name, s2w = c[0].quat_layout or (layout.order, layout.sensor_to_world)
            q = to_wxyz(c[3], order_name)
            c[3] = q if s2w else quat.conjugate(q)
    rate = min(c[5] for c in cleaned)
    rate = round(rate / _RATE_ROUNDING) * _RATE_ROUNDING
    t0 = max(c[1][0] for c in cleaned)
    t1 = min(c[1][-1] for c in cleaned)
    if not t1 > t0:
        raise CourtsideError("the sensors' recordings do not overlap in time")
    grid = t0 + np.arange(int(np.floor((t1 - t0) * rate + 1e-9)) + 1) / rate
    acc = np.stack([_interp(grid, t, a) for _, t, a, _, _, _ in cleaned], axis=1)
    has_q = all(c[3] is not None for c in cleaned)
    has_g = all(c[4] is not None for c in cleaned)
    quats = np.stack([_interp_quat(grid, t, q) for _, t, _, q, _, _ in cleaned], axis=1) if has_q else None
    gyro = np.stack([_interp(grid, t, g) for _, t, _, _, g, _ in cleaned], axis=1) if has_g else None
    report.update(fps=rate, samples=int(len(grid)), duration_s=round(float(grid[-1] - grid[0]), 4))
    return ImportedTake(rate, grid - grid[0], acc, [c[0].name for c in cleaned], [c[0].label for c in cleaned],
                        gyro, quats, report)
