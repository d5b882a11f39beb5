"""The calibration poses the wizard asks for: their geometry lives in the engine
(`engine.mocap.calibration_poses`, which the evaluation also simulates); here, what the operator is told."""
from __future__ import annotations

from engine.mocap.calibration_poses import (POSES, pose_rotations, reference_bow, reference_long_sit,
                                            reference_npose)

__all__ = ["POSES", "POSE_INSTRUCTIONS", "pose_rotations", "reference_bow", "reference_long_sit", "reference_npose"]

POSE_INSTRUCTIONS = {
    "npose": "Stand upright facing forward, arms straight down along the body, palms in, legs straight, "
             "feet under the hips. Hold still: capture starts by itself.",
    "tpose": "Stand upright facing forward, arms straight out to the sides at shoulder height, palms down, legs "
             "straight. Hold still: capture starts by itself.",
}
