"""Sensor calibration workflow (headless, pure logic): sensor->segment assignment, placement check, static
N-pose with a stillness gate, gravity alignment -> sensor-to-segment rotation, accelerometer norm check, sync
tap, quality score, versioned records.

Public API: :class:`CalibrationWizard` (``assign``, ``confirm``, ``redo``, ``push``, ``snapshot``, ``record``),
:class:`SegmentSpec`, :class:`WizardConfig`, :func:`segment_specs_from_placements`, :class:`CalibrationRecord`,
:class:`SensorCalibration`, :class:`CalibrationRecordError`, and the building blocks
:func:`sensor_to_segment_rotation`, :func:`rotation_from_directions`, :func:`fit_offset_g`, :func:`detect_tap`,
:func:`stillness`. The calibration pose of the standard set-up (reference N-pose) is built by
:mod:`gateway.calibration.pose`.
"""
from gateway.calibration.alignment import (
    fit_offset_g, minimal_rotation, norm_error_g, rotation_angle_deg, rotation_from_directions,
    sensor_to_segment_rotation, tilt_deg,
)
from gateway.calibration.errors import CalibrationRecordError
from gateway.calibration.record import CalibrationRecord, SensorCalibration
from gateway.calibration.signals import Stillness, TapEvent, detect_tap, stillness
from gateway.calibration.wizard import STEPS, CalibrationWizard, SegmentSpec, WizardConfig, segment_specs_from_placements

__all__ = [
    "fit_offset_g", "minimal_rotation", "norm_error_g", "rotation_angle_deg", "rotation_from_directions",
    "sensor_to_segment_rotation", "tilt_deg", "CalibrationRecordError", "CalibrationRecord", "SensorCalibration",
    "Stillness", "TapEvent", "detect_tap", "stillness", "STEPS", "CalibrationWizard", "SegmentSpec",
    "WizardConfig", "segment_specs_from_placements",
]
