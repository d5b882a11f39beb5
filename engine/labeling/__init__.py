"""Seed 001: online multi-subject marker labeling (Kalman gating, rigid-body fitting by exhaustive search,
greedy best-body-first assignment, missing-marker recovery) and its closest-point baseline.
See docs/engine-markers.md."""
from engine.labeling.baseline import ClosestPointTracker, bootstrap_training_labels
from engine.labeling.c3d_io import write_c3d
from engine.labeling.config import LabelingConfig
from engine.labeling.labeler import LOST, OBSERVED, RECOVERED, FrameLabels, OnlineLabeler

__all__ = [
    "ClosestPointTracker", "FrameLabels", "LOST", "LabelingConfig", "OBSERVED", "OnlineLabeler", "RECOVERED",
    "bootstrap_training_labels", "write_c3d",
]
