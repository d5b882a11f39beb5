"""Scores of the confidence-vs-error check (engine/evaluation/confidence_quality.py) on known answers."""
from __future__ import annotations

import numpy as np
import pytest

from engine.evaluation.confidence_quality import auc, confidence_quality


def test_auc_is_the_mann_whitney_probability():
    score = np.array([0.1, 0.4, 0.35, 0.8])
    positive = np.array([False, False, True, True])
    # pairs (pos, neg): (0.35 > 0.1) (0.35 < 0.4) (0.8 > 0.1) (0.8 > 0.4) -> 3 of 4
    assert auc(score, positive) == pytest.approx(0.75)
    assert auc(np.array([1.0, 1.0]), np.array([True, False])) == pytest.approx(0.5)  # a tie counts one half
    assert np.isnan(auc(score, np.zeros(4, bool)))


def test_a_confidence_that_falls_exactly_when_the_error_rises_scores_perfectly():
    fps = 10.0
    err = np.repeat([5.0, 30.0, 8.0, 40.0, 12.0], 10)  # per frame, 1 s each
    conf = np.repeat([0.9, 0.2, 0.8, 0.1, 0.7], 10)
    q = confidence_quality([conf[:20], conf[20:]], [err[:20], err[20:]], fps)
    assert (q.seconds, q.bad_seconds) == (5, 2)
    assert q.spearman == pytest.approx(-1.0) and q.auc == pytest.approx(1.0)
    assert (q.median_good, q.median_bad) == (pytest.approx(0.8), pytest.approx(0.15))
    flipped = confidence_quality([1 - conf], [err], fps)
    assert flipped.auc == pytest.approx(0.0) and flipped.spearman == pytest.approx(1.0)
