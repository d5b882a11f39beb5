"""Seed 002: joint centres (GDKE closed form refined on the geometric residual; sphere / circle / cylinder fits;
SCoRE as the two-segment peer) and skeleton fitting from labelled markers, replayed into an engine.mocap Motion.
See docs/engine-markers.md."""
from engine.skeleton_fit.gdke import (CircleFit, CylinderFit, DegenerateFitError, JointFit, JointFitConfig, JointType,
                                      PlaneFit, SphereFit, circle_fit, cylinder_fit, fit_joint, plane_fit, refine_centre,
                                      sphere_fit)
from engine.skeleton_fit.markerset import CMU_41, MARKER_SETS, PLUG_IN_GAIT, Landmark, MarkerSet, SegmentSpec, detect_marker_set
from engine.skeleton_fit.model import SkeletonFitConfig, SkeletonModel, fit_skeleton
from engine.skeleton_fit.motion import to_motion
from engine.skeleton_fit.score import score_centre

__all__ = [
    "CMU_41", "CircleFit", "CylinderFit", "DegenerateFitError", "JointFit", "JointFitConfig", "JointType", "Landmark",
    "MARKER_SETS", "MarkerSet", "PLUG_IN_GAIT", "PlaneFit", "SegmentSpec", "SkeletonFitConfig", "SkeletonModel",
    "SphereFit", "circle_fit", "cylinder_fit", "detect_marker_set", "fit_joint", "fit_skeleton", "plane_fit",
    "refine_centre", "score_centre", "sphere_fit", "to_motion",
]
