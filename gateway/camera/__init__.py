"""Overhead court camera: frame sources, court calibration, player tracking, IMU-camera lag check.

Headless (OpenCV + numpy only). Public API, all importable from here:

- frames: :class:`Frame`, :class:`FrameSource` protocol, :class:`OpenCVCamera`, :class:`VideoFileSource`,
  :class:`SyntheticCourtCamera` (+ :class:`GroundTruth`, :class:`CameraImperfections`, :func:`default_court_camera`)
- court: :data:`COURT_KEYPOINTS_M`, :data:`COURT_LINES_M`, :class:`CourtCalibration` (fit / save / load / map)
- tracking: :class:`PlayerTracker` (one athlete), :class:`MultiPlayerTracker` (one track per athlete),
  :class:`TrackerConfig`, :class:`TrackRecord`
- lag check: :func:`jump_lag` (one call), :func:`imu_event_signal`, :func:`camera_event_signal`,
  :func:`upward_image_displacement_px`,
  :func:`estimate_lag`, :class:`LagEstimate`
"""
from gateway.camera.court import COURT_KEYPOINTS_M, COURT_LINES_M, keypoints_array
from gateway.camera.court_calibration import CourtCalibration
from gateway.camera.errors import CameraError, CourtCalibrationFileError, FrameSourceError
from gateway.camera.lag import (
    LagEstimate, camera_event_signal, estimate_lag, imu_event_signal, jump_lag, upward_image_displacement_px,
)
from gateway.camera.paths import PlayerPath, jump_lift_m, scripted_rally_path
from gateway.camera.pinhole import PinholeCamera
from gateway.camera.sources import Frame, FrameSource, OpenCVCamera, VideoFileSource
from gateway.camera.synthetic import CameraImperfections, GroundTruth, SyntheticCourtCamera, default_court_camera
from gateway.camera.tracker import DEFAULT_ATHLETE, MultiPlayerTracker, PlayerTracker, TrackerConfig, TrackRecord

__all__ = [
    "COURT_KEYPOINTS_M", "COURT_LINES_M", "keypoints_array", "CourtCalibration", "CameraError",
    "CourtCalibrationFileError", "FrameSourceError", "LagEstimate", "camera_event_signal", "estimate_lag",
    "imu_event_signal", "jump_lag", "upward_image_displacement_px", "PlayerPath", "jump_lift_m", "scripted_rally_path",
    "PinholeCamera", "Frame", "FrameSource", "OpenCVCamera", "VideoFileSource", "CameraImperfections",
    "GroundTruth", "SyntheticCourtCamera", "default_court_camera", "PlayerTracker", "TrackerConfig", "TrackRecord",
    "MultiPlayerTracker", "DEFAULT_ATHLETE",
]
