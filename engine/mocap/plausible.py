"""One rule for numbers read from mocap text files: finite and of a size a body can have.

Why: ``float()`` accepts "nan", "inf" and "1e300", and numpy carries them silently into forward kinematics, a
NaN motion graph and, much later, a crash in synthesis far from the file that caused it. Rejecting them at the
reader names the file and line instead. 1e6 is far beyond any real value in any unit used (10 km in centimetres,
a million degrees of rotation) yet keeps forward kinematics far from overflow."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.errors import MalformedFileError

MAX_ABS_VALUE = 1e6


def check_values(path: Path, values: np.ndarray, what: str, lines: np.ndarray | int | None = None) -> None:
    """Raise MalformedFileError at the first value that is non-finite or larger than MAX_ABS_VALUE.

    ``lines``: the 1-based file line of each row of ``values`` (or one line for all, or None)."""
    values = np.asarray(values, dtype=float)
    bad = ~np.isfinite(values) | (np.abs(np.nan_to_num(values, nan=0.0)) > MAX_ABS_VALUE)
    if not bad.any():
        return
    first = tuple(np.argwhere(bad)[0])
    line = lines if lines is None or np.isscalar(lines) else int(np.asarray(lines)[first[0]])
    raise MalformedFileError(path, line, f"{what}: {values[first]!r} is not a finite number of plausible size "
                                         f"(|x| <= {MAX_ABS_VALUE:g}); {int(bad.sum())} such value(s)")
