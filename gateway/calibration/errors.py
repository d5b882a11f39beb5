"""Errors of the calibration package (names the file and the problem)."""
from __future__ import annotations

from pathlib import Path

from engine.errors import MalformedFileError


class CalibrationRecordError(MalformedFileError):
    """A saved sensor-calibration record is unreadable, of an unknown schema version, or inconsistent."""

    def __init__(self, path: str | Path, problem: str) -> None:
        super().__init__(path, None, problem)
        self.path = Path(path)
