"""Motion-capture data for the engine: readers (BVH, ASF/AMC, C3D), Skeleton/Motion and vectorised forward
kinematics, resampling and mirroring, joint roles, heading and foot contacts, virtual accelerometers,
gyroscopes and orientation filters with sensor-error models, placements calibrated from a sensor-calibration
record, and the CMU clips shipped in engine/data.

Conventions: world Y up, metres, seconds, quaternions (w, x, y, z), accelerations in g (docs/CONTRACTS.md)."""
from engine.errors import MalformedFileError
from engine.mocap.asf_amc import AsfSkeleton, read_amc, read_asf
from engine.mocap.bvh import CMU_UNIT_M, KNOWN_UNITS, read_bvh, write_bvh
from engine.mocap.c3d import MarkerData, read_c3d
from engine.mocap.calibrated import (SensorCalibrationData, calibrated_placements,
                                     load_sensor_calibration, placements_from_calibration, reading_corrections)
from engine.mocap.clips import DATA_DIR, default_cache_dir, load_clip, load_database, sample_clips
from engine.heading import SEED_HEADING_SPEED_MPS, seed_heading_rule
from engine.mocap.ground import (ContactThresholds, foot_contacts, ground_positions, heading_from_positions,
                                 root_heading, wrap_angle)
from engine.mocap.rest_pose import rebase_to_tpose, tpose_bases, tpose_skeleton
from engine.mocap.roles import ERROR_ROLES, ROLES, error_joint_indices, joint_roles, left_right_pairs
from engine.mocap.sensors import (GRAVITY_MPS2, SEED000_SENSORS, SEED003_SENSORS, SEED004_SENSORS,
                                  STANDARD_SENSORS, SensorErrorModel, SensorPlacement, mean_squared_error_g2,
                                  standard_placements, virtual_accelerometers, virtual_gyroscopes)
from engine.mocap.orientation import OrientationErrorModel, virtual_orientations
from engine.mocap.skeleton import Motion, Skeleton, forward_kinematics, pose_joint_positions
from engine.mocap.transform import mirror, resample

__all__ = [
    "AsfSkeleton", "CMU_UNIT_M", "ContactThresholds", "DATA_DIR", "ERROR_ROLES", "GRAVITY_MPS2", "KNOWN_UNITS",
    "MalformedFileError", "MarkerData", "Motion", "OrientationErrorModel", "ROLES", "SEED000_SENSORS", "SEED003_SENSORS",
    "SEED004_SENSORS", "STANDARD_SENSORS", "SensorCalibrationData", "SensorErrorModel", "SensorPlacement",
    "Skeleton", "calibrated_placements", "load_sensor_calibration", "placements_from_calibration",
    "reading_corrections",
    "SEED_HEADING_SPEED_MPS", "default_cache_dir", "error_joint_indices", "foot_contacts", "forward_kinematics", "pose_joint_positions", "ground_positions", "seed_heading_rule",
    "heading_from_positions", "joint_roles", "left_right_pairs", "load_clip", "load_database",
    "mean_squared_error_g2", "mirror", "read_amc", "read_asf", "read_bvh", "read_c3d", "rebase_to_tpose", "resample",
    "root_heading", "sample_clips", "standard_placements", "tpose_bases", "tpose_skeleton",
    "virtual_accelerometers", "virtual_gyroscopes", "virtual_orientations",
    "wrap_angle", "write_bvh",
]
