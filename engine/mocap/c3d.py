"""C3D marker reader (via ezc3d, which handles every processor type and parameter-section variant).

Returns marker trajectories in metres in the file's own lab frame (C3D files are usually Z up; this module
does not guess an axis change, the marker-labelling code decides). A sample is missing (NaN) when its
residual is negative (the C3D convention for "not reconstructed") or the file stores it as NaN."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.errors import MalformedFileError
from engine.mocap.c3d_check import check_c3d
from engine.mocap.plausible import check_values

_UNIT_M = {"mm": 0.001, "cm": 0.01, "dm": 0.1, "m": 1.0, "in": 0.0254, "inch": 0.0254}


@dataclass(eq=False)
class MarkerData:
    """Labelled marker trajectories: `positions_m` (F, M, 3) metres, NaN where the marker is missing."""

    labels: tuple[str, ...]
    positions_m: np.ndarray
    fps: float
    name: str = ""

    @property
    def n_frames(self) -> int:
        return self.positions_m.shape[0]


def read_c3d(path: str | Path) -> MarkerData:
    """Read the POINT data of a C3D file, honouring POINT:UNITS and POINT:RATE."""
    import ezc3d  # imported here: only marker work needs the compiled extension

    path = Path(path)
    if not path.is_file():
        raise MalformedFileError(path, None, "no such file")
    check_c3d(path)  # ezc3d crashes on damaged parameters and accepts a cut file
    try:
        c3d = ezc3d.c3d(str(path))
    except Exception as exc:  # ezc3d raises plain RuntimeError/ValueError with terse text
        raise MalformedFileError(path, None, f"not a readable C3D file ({exc})") from None
    point = c3d["parameters"].get("POINT", {})
    try:
        labels = tuple(str(s).strip() for s in point["LABELS"]["value"])
        rate = float(point["RATE"]["value"][0])
    except (KeyError, IndexError):
        raise MalformedFileError(path, None, "POINT:LABELS or POINT:RATE parameter missing") from None
    declared = list(point.get("UNITS", {}).get("value", []))
    units = str(declared[0]).strip().lower() if declared and str(declared[0]).strip() else "mm"  # C3D default
    if units not in _UNIT_M:
        raise MalformedFileError(path, None, f"unknown POINT:UNITS {units!r}")
    if not rate > 0:
        raise MalformedFileError(path, None, f"POINT:RATE must be positive, got {rate}")
    points = np.asarray(c3d["data"]["points"], float)  # (4, M, F)
    residuals = np.asarray(c3d["data"]["meta_points"]["residuals"], float)  # (1, M, F)
    xyz = np.transpose(points[:3], (2, 1, 0))  # file units
    if len(labels) < xyz.shape[1]:
        raise MalformedFileError(path, None, f"{xyz.shape[1]} markers but only {len(labels)} labels")
    missing = np.transpose(residuals[0] < 0)  # (F, M)
    xyz[missing] = np.nan
    _check_plausible(path, xyz, units)
    return MarkerData(labels[: xyz.shape[1]], xyz * _UNIT_M[units], rate, path.stem)


def _check_plausible(path: Path, xyz: np.ndarray, units: str) -> None:
    """Refuse a file with no marker sample at all, and coordinates no lab can hold (|x| > 1e6 in the file's
    units, as BVH/ASF/AMC: `engine.mocap.plausible`), before anything computes on them (issue 22: an all-NaN
    C3D was 'labelled' with exit 0 and a RuntimeWarning; 1e30 was accepted)."""
    present = ~np.isnan(xyz)
    if not present.any():
        raise MalformedFileError(path, None, f"no marker sample in any of the {xyz.shape[0]} frames (every point "
                                             "missing or NaN)")
    check_values(path, xyz[present], f"POINT data ({units})")
