"""Seed 002: closed-form joint centres (GDKE sphere / circle / cylinder fits) and skeleton fitting from labelled
markers, replayed into an engine.mocap Motion. See docs/engine-markers.md."""
from engine.skeleton_fit.gdke import (CircleFit, CylinderFit, DegenerateFitError, JointFit, JointFitConfig, JointType,
                                      PlaneFit, SphereFit, circle_fit, cylinder_fit, fit_joint, plane_fit, sphere_fit)
from engine.skeleton_fit.markerset import CMU_41, MARKER_SETS, PLUG_IN_GAIT, Landmark, MarkerSet, SegmentSpec, detect_marker_set
from engine.skeleton_fit.model import SkeletonFitConfig, SkeletonModel, fit_skeleton
from engine.skeleton_fit.motion import to_motion

__all__ = [
    "CMU_41", "CircleFit", "CylinderFit", "DegenerateFitError", "JointFit", "JointFitConfig", "JointType", "Landmark",
    "MARKER_SETS", "MarkerSet", "PLUG_IN_GAIT", "PlaneFit", "SegmentSpec", "SkeletonFitConfig", "SkeletonModel",
    "SphereFit", "circle_fit", "cylinder_fit", "detect_marker_set", "fit_joint", "fit_skeleton", "plane_fit",
    "sphere_fit", "to_motion",
]
