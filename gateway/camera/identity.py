"""Scoring several tracks against the synthetic court's ground truth: identity swaps and position error per athlete.

Why a module (not test code): the test and ``python -m gateway.camera.bench`` must count swaps and errors the same
way. A frame counts as a *swap* for an athlete when its track is nearer the other athlete's true position than to
its own while the two stand more than ``apart_m`` apart (closer than that, who is who is not measurable from
positions). Position error is scored only where the athlete stands inside the tracked region by ``inset_m`` (a
body half out of the region is clipped by it; a track that has left is meant to be reported lost, not scored).
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from gateway.camera.court import HALF_DOUBLES_M, HALF_LENGTH_M
from gateway.camera.paths import PlayerPath
from gateway.camera.sources import Frame
from gateway.camera.tracker import MultiPlayerTracker


@dataclass
class AthleteScore:
    """One athlete's tally over a run."""

    errors_m: list[float] = field(default_factory=list)
    swap_frames: int = 0
    in_region_frames: int = 0
    statuses: list[str] = field(default_factory=list)

    @property
    def rms_m(self) -> float:
        return float(np.sqrt(np.mean(np.square(self.errors_m)))) if self.errors_m else float("nan")

    @property
    def detected(self) -> float:
        """Share of in-region frames with a reported position."""
        return len(self.errors_m) / max(self.in_region_frames, 1)

    @property
    def losses(self) -> int:
        """Times the track went from live to lost."""
        return sum(1 for a, b in zip(self.statuses, self.statuses[1:]) if b == "lost" and a != "lost")


def score_tracks(frames: Iterable[Frame], tracker: MultiPlayerTracker, truth: Mapping[str, PlayerPath], *,
                 margin_m: float, apart_m: float = 1.0, inset_m: float = 1.0) -> dict[str, AthleteScore]:
    """Run ``tracker`` over ``frames`` (synthetic: ``frame.truth.t_true_s`` is the true time) and score each
    athlete against ``truth[name]``; ``margin_m`` is the tracker's run-off margin around the court."""
    scores = {name: AthleteScore() for name in truth}
    half = np.array([HALF_DOUBLES_M, HALF_LENGTH_M]) + margin_m - inset_m
    for frame in frames:
        records = tracker.update(frame)
        status = tracker.status()
        t = frame.truth.t_true_s
        true_xy = {name: np.array([(s := path.state(t)).x_m, s.y_m]) for name, path in truth.items()}
        on_court = t >= min(float(p.t_s[0]) for p in truth.values())
        for name, score in scores.items():
            score.statuses.append(status[name])
            mine = true_xy[name]
            if not on_court or np.any(np.abs(mine) > half):
                continue
            score.in_region_frames += 1
            rec = records[name]
            if rec is None:
                continue
            xy = np.array([rec.x_m, rec.y_m])
            score.errors_m.append(float(np.linalg.norm(xy - mine)))
            others = [p for n, p in true_xy.items() if n != name and np.linalg.norm(p - mine) > apart_m]
            score.swap_frames += any(np.linalg.norm(xy - p) < np.linalg.norm(xy - mine) for p in others)
    return scores
