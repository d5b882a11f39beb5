"""Write labelled marker trajectories to C3D (ezc3d); reading is engine.mocap.read_c3d.

Why metres: Courtside works in metres throughout, and POINT:UNITS = 'm' makes the file self-describing.
NaN samples are written as C3D missing points (residual −1), which read_c3d turns back into NaN.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.mocap import MarkerData


def write_c3d(path: str | Path, data: MarkerData) -> None:
    """Write ``data`` (labels, positions_m (F,M,3) with NaN = missing, fps) as a C3D file."""
    import ezc3d  # compiled extension: imported only for marker work

    c3d = ezc3d.c3d()
    point = c3d["parameters"]["POINT"]
    point["RATE"]["value"] = [float(data.fps)]
    point["LABELS"]["value"] = list(data.labels)
    point["UNITS"]["value"] = ["m"]
    frames, markers = data.positions_m.shape[:2]
    points = np.ones((4, markers, frames))
    points[:3] = np.nan_to_num(data.positions_m.transpose(2, 1, 0), nan=0.0)
    c3d["data"]["points"] = points
    missing = np.isnan(data.positions_m).any(axis=2).T
    c3d["data"]["meta_points"]["residuals"] = np.where(missing, -1.0, 0.0)[None]
    c3d["data"]["meta_points"]["camera_masks"] = np.zeros((7, markers, frames), dtype=bool)
    c3d.write(str(path))
