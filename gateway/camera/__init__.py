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
from importlib import import_module

#: public name -> the submodule defining it. Loaded on first use (PEP 562): `import gateway.camera.<module>` runs
#: this file first, and eager imports here put scipy.signal (the lag check) and more into every gateway that only
#: tracks -- ~60 MB of resident memory on the court's board, whose budget is 100 MB (issue 20).
_WHERE = {
    **dict.fromkeys(("COURT_KEYPOINTS_M", "COURT_LINES_M", "keypoints_array"), "court"),
    "CourtCalibration": "court_calibration",
    **dict.fromkeys(("CameraError", "CourtCalibrationFileError", "FrameSourceError"), "errors"),
    **dict.fromkeys(("LagEstimate", "camera_event_signal", "estimate_lag", "imu_event_signal", "jump_lag",
                     "upward_image_displacement_px"), "lag"),
    **dict.fromkeys(("PlayerPath", "jump_lift_m", "scripted_rally_path"), "paths"),
    "PinholeCamera": "pinhole",
    **dict.fromkeys(("Frame", "FrameSource", "OpenCVCamera", "VideoFileSource"), "sources"),
    **dict.fromkeys(("CameraImperfections", "GroundTruth", "SyntheticCourtCamera", "default_court_camera"),
                    "synthetic"),
    **dict.fromkeys(("DEFAULT_ATHLETE", "MultiPlayerTracker", "PlayerTracker", "TrackerConfig", "TrackRecord"),
                    "tracker"),
}
__all__ = list(_WHERE)


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module 'gateway.camera' has no attribute {name!r}")
    return getattr(import_module(f"gateway.camera.{_WHERE[name]}"), name)
