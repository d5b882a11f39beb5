"""Errors of the calibration package (names the file and the problem)."""
from __future__ import annotations

from pathlib import Path


class CalibrationRecordError(Exception):
    """A saved sensor-calibration record is unreadable, of an unknown schema version, or inconsistent."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")
