"""Marker trajectories in and out of C3D files (ezc3d), in metres with NaN for missing samples.

Why here: the labeler writes a labelled C3D, and both CLIs read marker C3Ds. Reading converts the file's
POINT:UNITS to metres (Courtside's unit) and turns ezc3d's missing samples (NaN, or a negative residual) into NaN.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

_UNIT_TO_M = {"m": 1.0, "cm": 0.01, "mm": 0.001}


@dataclass
class MarkerData:
    """labels: M marker names; positions_m: (F,M,3) metres, NaN where missing; rate_hz: frames per second."""

    labels: list[str]
    positions_m: np.ndarray
    rate_hz: float

    def as_dict(self) -> dict[str, np.ndarray]:
        """{label: (F,3)} view, the form fit_skeleton takes."""
        return {label: self.positions_m[:, i] for i, label in enumerate(self.labels)}


def _error(path: Path, problem: str) -> Exception:
    try:
        from engine.errors import MalformedFileError
    except ImportError:  # engine.errors belongs to the engine-data part; fall back to a plain, still-clear error
        return ValueError(f"{path}: {problem}")
    return MalformedFileError(path, None, problem)


def read_markers(path: str | Path) -> MarkerData:
    """Read every POINT of a C3D file. Raises a clear error naming the file if it is missing or not a C3D."""
    import ezc3d

    path = Path(path)
    if not path.is_file():
        raise _error(path, "file not found")
    try:
        c3d = ezc3d.c3d(str(path))
    except Exception as exc:  # ezc3d raises bare RuntimeError/IOError with terse text
        raise _error(path, f"not a readable C3D file ({exc})") from exc
    point = c3d["parameters"]["POINT"]
    labels = list(point["LABELS"]["value"])
    units = (point.get("UNITS", {}).get("value") or ["mm"])[0].strip().lower() or "mm"
    if units not in _UNIT_TO_M:
        raise _error(path, f"unsupported POINT:UNITS {units!r} (expected one of {sorted(_UNIT_TO_M)})")
    data = c3d["data"]["points"][:3].transpose(2, 1, 0).astype(float) * _UNIT_TO_M[units]
    residuals = c3d["data"]["meta_points"]["residuals"][0].T
    data[residuals < 0] = np.nan
    rate = float(point["RATE"]["value"][0])
    if len(labels) != data.shape[1] or rate <= 0:
        raise _error(path, f"{data.shape[1]} points but {len(labels)} labels, rate {rate}")
    return MarkerData(labels[: data.shape[1]], data, rate)


def write_markers(path: str | Path, data: MarkerData) -> None:
    """Write a C3D in metres (POINT:UNITS = 'm'); NaN samples become ezc3d's missing points (residual −1)."""
    import ezc3d

    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [float(data.rate_hz)]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = list(data.labels)
    c3d["parameters"]["POINT"]["UNITS"]["value"] = ["m"]
    frames, markers = data.positions_m.shape[:2]
    points = np.ones((4, markers, frames))
    points[:3] = data.positions_m.transpose(2, 1, 0)
    c3d["data"]["points"] = points
    missing = np.isnan(data.positions_m).any(axis=2).T
    residuals = np.where(missing, -1.0, 0.0)[None]
    c3d["data"]["meta_points"]["residuals"] = residuals
    c3d["data"]["meta_points"]["camera_masks"] = np.zeros((7, markers, frames), dtype=bool)
    c3d.write(str(path))
