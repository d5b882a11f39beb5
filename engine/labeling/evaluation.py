"""Score the online labeler on one real take: accuracy over time, forced losses, closest-point baseline.

Why its own module: `courtside label --degrade` and bench/bench_labeling.py must report the same numbers on the
same stream, so the protocol lives here once. The protocol (issue 14):
  1. degrade the file's own labelled trajectories (shuffle, noise, gaps ≤ 20 frames, ghosts; scenario.degrade);
  2. train on the first frames, label the rest online;
  3. force losses: every ``forced_every_s`` one rigid body (cycling through them) vanishes for
     ``forced_duration_s``; the time until its visible markers that were labelled correctly before the loss
     are all labelled correctly again is the re-acquisition time;
  4. score accuracy per ``window_s`` window so a labeler that degrades along a long take shows it, next to the
     one-to-one closest-point baseline on the very same stream.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from engine.mocap import MarkerData

from .baseline import ClosestPointTracker, bootstrap_training_labels
from .config import LabelingConfig
from .labeler import LOST, OBSERVED, RECOVERED, FrameLabels, OnlineLabeler
from .scenario import DegradeConfig, Score, Stream, degrade, score_frame


@dataclass(frozen=True)
class ForcedLoss:
    """Labels removed from the stream over frames [start, end)."""

    labels: np.ndarray
    start: int
    end: int


@dataclass
class TakeEvaluation:
    """Everything the CLI and the bench print for one take (fractions over the labelled frames after training)."""

    name: str
    n_frames: int
    fps: float
    n_labels: int
    body_sizes: list[int]
    score: Score
    baseline: Score
    window_accuracy: list[float]  # labeler accuracy per window_s window (last window may be shorter)
    baseline_window_accuracy: list[float]
    status_fractions: tuple[float, float, float]  # observed, recovered, lost
    reacquire_s: list[float] = field(default_factory=list)  # per forced loss; inf if never re-acquired
    frames_per_s: float = float("nan")
    mean_candidates: float = float("nan")

    @property
    def recovered_error_mm(self) -> float:
        """Median distance of recovered (reported but not visible) markers from their true position, mm."""
        return 1000 * float(np.median(self.score.recovery_err_m)) if self.score.recovery_err_m else float("nan")


def default_train_frames(n_frames: int, fps: float, train_s: float = 10.0) -> int:
    """The training window `courtside label` uses without --train-frames: ``train_s`` seconds, at most half the
    take, at least the paper's 50 frames (so a take of 50 frames or fewer is refused as too short). Why seconds: the clustering needs the segments to move relative to each other, and 50 frames are
    0.4 s at 120 Hz (a break dancer standing still), 1 s at 50 Hz; 3 s of a tennis serve still cluster a whole
    arm into one body (accuracy 0.80 on the one-player serve), 5 s separate it (0.975); on the long CMU takes
    and the jyu dances 10 s beat 5 s (cmu_135_02 0.911 -> 0.983, jyu_dance2 0.760 -> 0.838)."""
    return max(LabelingConfig.train_frames, min(int(round(train_s * fps)), n_frames // 2))


def force_losses(stream: Stream, bodies: list[np.ndarray], first: int, fps: float, every_s: float,
                 duration_s: float) -> list[ForcedLoss]:
    """Remove one rigid body's points from ``stream`` for ``duration_s`` in the middle of every ``every_s`` window
    from frame ``first`` on, cycling through ``bodies``. Modifies the stream in place (clouds, truth, visible)."""
    if not bodies or every_s <= 0 or duration_s <= 0:
        return []
    every, length = max(int(round(every_s * fps)), 1), max(int(round(duration_s * fps)), 1)
    losses = []
    for k, start in enumerate(range(first + every // 2, len(stream.clouds) - length, every)):
        labels = np.asarray(bodies[k % len(bodies)])
        losses.append(ForcedLoss(labels, start, start + length))
        for t in range(start, start + length):
            keep = ~np.isin(stream.truth[t], labels)
            stream.clouds[t], stream.truth[t] = stream.clouds[t][keep], stream.truth[t][keep]
        stream.visible[start : start + length, labels] = False
    return losses


def reacquisition_s(loss: ForcedLoss, stream: Stream, picks: list[np.ndarray], first: int, fps: float) -> float:
    """Seconds after the body reappears until every visible marker of it that was labelled correctly in the frame
    before the loss is labelled correctly again (inf if that does not happen before the take ends).

    Why "correct before the loss": a marker the labeler already had wrong or missing before the body was removed
    (a swap from an earlier gap) would make every later loss of that body read "never", which measures that
    old error, not re-acquisition; its cost shows in the accuracy. If no marker of the body was correct before
    the loss, all of its visible markers must be."""
    labels = loss.labels
    before = loss.start - 1
    if before >= first:
        got = picks[before - first][labels]
        correct = stream.visible[before, labels] & (got >= 0)
        correct[correct] = stream.truth[before][got[correct]] == labels[correct]
        if correct.any():
            labels = labels[correct]
    for t in range(loss.end, len(stream.clouds)):
        label_point = picks[t - first]
        vis = labels[stream.visible[t, labels]]
        got = label_point[vis]
        if len(vis) and (got >= 0).all() and (stream.truth[t][got] == vis).all():
            return (t - loss.end) / fps
    return float("inf")


def _window_scores(n: int) -> list[Score]:
    return [Score() for _ in range(n)]


def run_labeler(training_m: np.ndarray, subjects: np.ndarray, fps: float, clouds: list[np.ndarray],
                config: LabelingConfig) -> tuple[OnlineLabeler, list[FrameLabels], float]:
    """Train on ``training_m`` and label every cloud. Returns (labeler, results, frames/s of CPU time)."""
    labeler = OnlineLabeler(config)
    labeler.train(training_m, subjects, fps)
    start = time.process_time()
    results = [labeler.step(cloud) for cloud in clouds]
    elapsed = max(time.process_time() - start, 1e-9)
    return labeler, results, len(results) / elapsed


def evaluate_take(
    data: MarkerData,
    subjects: np.ndarray,
    config: LabelingConfig,
    seed: int,
    bootstrap: bool = False,
    degrade_config: DegradeConfig | None = None,
    window_s: float = 10.0,
    forced_every_s: float = 10.0,
    forced_duration_s: float = 0.5,
) -> tuple[TakeEvaluation, np.ndarray, list[FrameLabels]]:
    """Degrade ``data``, label it online, score it. Returns (evaluation, labelled positions (F,L,3), results).

    Positions: training frames as trained on, then observed or recovered positions (NaN when lost)."""
    train = config.train_frames
    if data.n_frames <= train:
        raise ValueError(f"{data.name}: {data.n_frames} frames, not more than the {train} training frames")
    dcfg = degrade_config or DegradeConfig(protect_frames=train)
    stream = degrade(data.positions_m, subjects, dcfg, np.random.default_rng(seed))
    training = data.positions_m[:train]
    if bootstrap:
        training = bootstrap_training_labels(training[0], stream.clouds[1:train])
    probe = OnlineLabeler(config)
    probe.train(training, subjects, data.fps)  # the bodies the forced losses remove
    losses = force_losses(stream, probe.bodies, train, data.fps, forced_every_s, forced_duration_s)
    labeler, results, fps_cpu = run_labeler(training, subjects, data.fps, stream.clouds[train:], config)

    per_window = max(int(round(window_s * data.fps)), 1)
    n_windows = -(-(data.n_frames - train) // per_window)
    ours, base = Score(), Score()
    ours_w, base_w = _window_scores(n_windows), _window_scores(n_windows)
    tracker = ClosestPointTracker(_last_seen(training))
    out = np.full_like(data.positions_m, np.nan)
    out[:train] = training
    for i, result in enumerate(results):
        t = train + i
        recovered = np.where((result.status == RECOVERED)[:, None], result.positions_m, np.nan)
        picks = tracker.step(stream.clouds[t])
        score_frame(ours, stream, t, result.label_point, recovered)
        score_frame(ours_w[i // per_window], stream, t, result.label_point)
        score_frame(base, stream, t, picks)
        score_frame(base_w[i // per_window], stream, t, picks)
        out[t] = np.where((result.status == LOST)[:, None], np.nan, result.positions_m)
    status = np.array([r.status for r in results])
    label_points = [r.label_point for r in results]
    evaluation = TakeEvaluation(
        name=data.name, n_frames=data.n_frames, fps=data.fps, n_labels=len(subjects),
        body_sizes=sorted(len(b) for b in labeler.bodies), score=ours, baseline=base,
        window_accuracy=[w.accuracy for w in ours_w], baseline_window_accuracy=[w.accuracy for w in base_w],
        status_fractions=(float(np.mean(status == OBSERVED)), float(np.mean(status == RECOVERED)),
                          float(np.mean(status == LOST))),
        reacquire_s=[reacquisition_s(loss, stream, label_points, train, data.fps) for loss in losses],
        frames_per_s=fps_cpu, mean_candidates=float(np.mean([r.mean_candidates for r in results])),
    )
    return evaluation, out, results


def _last_seen(frames_m: np.ndarray) -> np.ndarray:
    """(T,L,3) → (L,3): each label's last non-NaN position (NaN if never seen), the baseline's starting point."""
    seen = ~np.isnan(frames_m).any(axis=2)
    last = len(frames_m) - 1 - np.argmax(seen[::-1], axis=0)
    out = frames_m[last, np.arange(frames_m.shape[1])]
    out[~seen.any(axis=0)] = np.nan
    return out
