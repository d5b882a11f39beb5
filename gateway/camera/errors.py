"""Errors raised by the camera package.

Why our own types: the gateway must report *which* file or device failed and why; they derive from the project's
error root (`engine.errors`, a dependency-free module) so every CLI reports them the same way."""
from __future__ import annotations

from pathlib import Path

from engine.errors import CourtsideError, MalformedFileError


class CameraError(CourtsideError):
    """Base class for camera-side failures (device, video file, calibration file)."""


class FrameSourceError(CameraError):
    """A frame source could not be opened or read (names the device or file)."""

    def __init__(self, source: str, problem: str) -> None:
        self.source = source
        self.problem = problem
        super().__init__(f"{source}: {problem}")


class CourtCalibrationFileError(CameraError, MalformedFileError):
    """A saved court calibration is unreadable or inconsistent (names the file and the problem)."""

    def __init__(self, path: str | Path, problem: str) -> None:
        MalformedFileError.__init__(self, path, None, problem)
        self.path = Path(path)
