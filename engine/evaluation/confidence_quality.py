"""How well the online decoder's per-frame confidence (engine/graph/confidence.py) tells an operator when the
engine is lost, measured on held-out takes: per second, the mean confidence against the mean global joint error.

* Spearman's rank correlation of confidence and error (-1: the lower the confidence, the larger the error;
  0: no relation);
* AUC of (1 - confidence) as a detector of the seconds whose error exceeds `threshold_cm` (15 cm, the issue's
  global-error target): the probability that a random bad second has a lower confidence than a random good one
  (0.5 = chance, 1 = perfect). Ties count one half (the Mann-Whitney statistic).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import rankdata, spearmanr

from .metrics import per_second


@dataclass(frozen=True)
class ConfidenceQuality:
    seconds: int
    bad_seconds: int  # seconds with mean error above the threshold
    spearman: float
    auc: float
    median_good: float  # median confidence of the good / bad seconds
    median_bad: float

    def line(self, threshold_cm: float) -> str:
        return (f"confidence vs per-second global error over {self.seconds} s: Spearman {self.spearman:+.2f}, "
                f"AUC(error > {threshold_cm:g} cm) {self.auc:.2f} ({self.bad_seconds} bad seconds; median "
                f"confidence {self.median_good:.2f} good, {self.median_bad:.2f} bad)")


def auc(score: np.ndarray, positive: np.ndarray) -> float:
    """Area under the ROC curve of `score` for the `positive` class (Mann-Whitney U / (n_pos n_neg))."""
    n_pos, n_neg = int(positive.sum()), int((~positive).sum())
    if n_pos == 0 or n_neg == 0:
        return float("nan")
    ranks = rankdata(score)
    return float((ranks[positive].sum() - n_pos * (n_pos + 1) / 2) / (n_pos * n_neg))


def confidence_quality(confidence: list[np.ndarray], error_cm: list[np.ndarray], fps: float,
                       threshold_cm: float = 15.0) -> ConfidenceQuality:
    """Per-frame confidence and error of each take -> per-second means pooled over the takes -> the scores."""
    conf = np.concatenate([per_second(c, fps) for c in confidence])
    err = np.concatenate([per_second(e, fps) for e in error_cm])
    bad = err > threshold_cm
    rho = float(spearmanr(conf, err).statistic) if len(conf) > 2 and np.ptp(conf) > 0 else float("nan")
    return ConfidenceQuality(len(conf), int(bad.sum()), rho, auc(-conf, bad),
                             float(np.median(conf[~bad])) if (~bad).any() else float("nan"),
                             float(np.median(conf[bad])) if bad.any() else float("nan"))
