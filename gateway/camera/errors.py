"""Errors raised by the camera package.

Why our own types: the gateway must report *which* file or device failed and why, without importing the
engine's error module into the headless capture path."""
from __future__ import annotations

from pathlib import Path


class CameraError(Exception):
    """Base class for camera-side failures (device, video file, calibration file)."""


class FrameSourceError(CameraError):
    """A frame source could not be opened or read (names the device or file)."""

    def __init__(self, source: str, problem: str) -> None:
        self.source = source
        self.problem = problem
        super().__init__(f"{source}: {problem}")


class CourtCalibrationFileError(CameraError):
    """A saved court calibration is unreadable or inconsistent (names the file and the problem)."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")
