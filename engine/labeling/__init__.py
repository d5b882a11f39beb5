"""Seed 001: online multi-subject marker labeling (Kalman gating, rigid-body fitting by exhaustive search,
greedy best-body-first assignment, re-acquisition by shape, swap repair, bounded missing-marker recovery), its
closest-point baseline and the evaluation protocol of `courtside label --degrade`.
See docs/engine-markers.md."""
from engine.labeling.baseline import ClosestPointTracker, bootstrap_training_labels
from engine.labeling.c3d_io import write_c3d
from engine.labeling.config import LabelingConfig
from engine.labeling.evaluation import TakeEvaluation, evaluate_take
from engine.labeling.labeler import LOST, OBSERVED, RECOVERED, FrameLabels, OnlineLabeler

__all__ = [
    "ClosestPointTracker", "FrameLabels", "LOST", "LabelingConfig", "OBSERVED", "OnlineLabeler", "RECOVERED",
    "TakeEvaluation", "bootstrap_training_labels", "evaluate_take", "write_c3d",
]
