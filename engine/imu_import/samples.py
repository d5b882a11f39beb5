"""Per-sample rules for the values of a recorded stream: a missing value (NaN, an empty field) is a missing
sample, an infinite or physically impossible one is refused naming its line.

Why refuse rather than drop: ``inf`` or 1e300 in an acceleration column is never a reading, it is a broken
export or a wrong column, and dropping it silently would hide that (issue 30: 1e300 accelerations were accepted,
``inf`` in a quaternion became NaN in the take)."""
from __future__ import annotations

import numpy as np

from engine.imu_import.origin import Origin, stream_error
from engine.recording_limits import MAX_ACC_G


def missing_rows(values: np.ndarray, origin: Origin | None, label: str, what: str) -> np.ndarray:
    """Mask (N,) of rows of ``values`` (N, K) with a NaN (missing samples); an infinite value is refused."""
    v = np.asarray(values, float)
    infinite = np.isinf(v).any(axis=1)
    if infinite.any():
        i = int(np.argmax(infinite))
        raise stream_error(origin, label, i, f"{what} {v[i].tolist()} holds an infinite value")
    return np.isnan(v).any(axis=1)


def check_acceleration_range(acc_g: np.ndarray, origin: Origin | None, label: str) -> None:
    """Refuse an acceleration component beyond +-`MAX_ACC_G` (NaN rows are missing samples, not checked)."""
    a = np.asarray(acc_g, float)
    beyond = (np.abs(np.nan_to_num(a)) > MAX_ACC_G).any(axis=1)
    if beyond.any():
        i = int(np.argmax(beyond))
        raise stream_error(origin, label, i, f"acceleration {np.round(a[i], 6).tolist()} g is beyond "
                                             f"+-{MAX_ACC_G:g} g (no worn sensor reads that: a wrong column or unit)")
