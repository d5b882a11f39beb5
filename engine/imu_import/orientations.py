"""The one rule for orientations read from a device file: a missing one stays missing (NaN), a wrong one is
refused; none is ever invented.

Why (issue 30): `quaternions.normalize` turns a zero (or NaN) quaternion into the identity, so missing
orientations in MVNX, MT text, x-IMU3 and CSV files became "sensor level, facing north" with exit 0, accelerations
were rebuilt in that invented frame, and calibrate graded them "good". Per row:

* a NaN anywhere (an empty field, a dropped packet) or all four zero (what loggers write before the orientation
  filter has a solution) -> missing: the row is NaN in the take, which the engine treats as "no orientation
  here" (an MVNX/DOT acceleration rebuilt from free acceleration is then missing too);
* an infinite value -> refused (`samples.missing_rows`);
* a finite quaternion whose norm is more than `QUAT_NORM_TOLERANCE` from 1 -> refused naming the line: a wrong
  column map, or Euler angles in quaternion columns (MT Manager can export either);
* a stream with no orientation at all -> refused: its orientation columns hold nothing, and the user mapped them.

Unit rows are renormalised (4- and 6-decimal exports are a little off unit length)."""
from __future__ import annotations

import numpy as np

from engine.imu_import.origin import Origin, stream_error
from engine.imu_import.samples import missing_rows
from engine.recording_limits import QUAT_NORM_TOLERANCE


def orientation_rows(q_file: np.ndarray, origin: Origin | None, label: str) -> np.ndarray:
    """``q_file`` (N, 4) in file order with unit rows renormalised and missing rows NaN (see the module doc)."""
    q = np.asarray(q_file, float)
    missing = missing_rows(q, origin, label, "orientation")
    norm = np.linalg.norm(np.where(missing[:, None], 0.0, q), axis=1)
    missing |= norm == 0.0
    bad = ~missing & (np.abs(norm - 1.0) > QUAT_NORM_TOLERANCE)
    if bad.any():
        i = int(np.argmax(bad))
        raise stream_error(origin, label, i, f"orientation {np.round(q[i], 6).tolist()} is not a unit quaternion "
                                             f"(norm {norm[i]:.4g}): wrong columns, or Euler angles in the "
                                             "quaternion columns")
    if missing.all():
        raise stream_error(origin, label, None, f"no orientation in any of its {len(q)} samples (all missing, NaN "
                                                "or zero)")
    return np.where(missing[:, None], np.nan, q / np.where(missing, 1.0, norm)[:, None])
