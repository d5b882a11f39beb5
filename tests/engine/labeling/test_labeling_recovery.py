"""Labeling that survives long takes (issue 14): re-acquisition by shape, bounded recovery, swap repair, held
structure model, no numeric failure on incomplete training frames, and the evaluation protocol itself.

Synthetic scenes with exact answers; each test fails on the labeler before issue 14 (noted per test)."""
from __future__ import annotations

import numpy as np
import pytest

from engine.labeling.baseline import ClosestPointTracker, bootstrap_training_labels
from engine.labeling.config import LabelingConfig
from engine.labeling.evaluation import evaluate_take, force_losses, reacquisition_s
from engine.labeling.labeler import LOST, RECOVERED, OnlineLabeler
from engine.labeling.reacquire import reacquire_body
from engine.labeling.scenario import DegradeConfig, degrade
from engine.labeling.structure import DistanceWindow, pair_distances
from engine.mocap import MarkerData

FPS = 120.0


def _rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _walking_scene(rng, frames, speed_mps=0.5, per_body=5):
    """One subject of three rigid bodies (0.35 m apart, no two alike) walking along x and turning slowly."""
    local = rng.uniform(-0.1, 0.1, (3, per_body, 3))
    offsets = np.array([[0.0, 0, 1.0], [0.0, 0.35, 1.0], [0.0, 0.7, 1.0]])
    t = np.arange(frames) / FPS
    pos = np.zeros((frames, 3 * per_body, 3))
    for b in range(3):
        ang = 0.5 * np.sin(0.7 * t + b)
        c, s = np.cos(ang), np.sin(ang)
        rot = np.stack([np.stack([c, -s, 0 * c], -1), np.stack([s, c, 0 * c], -1),
                        np.stack([0 * c, 0 * c, 1 + 0 * c], -1)], -2)
        pos[:, per_body * b : per_body * (b + 1)] = (np.einsum("fij,nj->fni", rot, local[b])
                                                     + (offsets[b] + np.outer(t, [speed_mps, 0, 0]))[:, None])
    return pos, np.zeros(3 * per_body, int)


def test_reacquire_body_finds_a_body_by_shape_alone_and_refuses_ghosts():
    rng = np.random.default_rng(1)
    template = rng.uniform(-0.1, 0.1, (5, 3))
    mean, std = pair_distances(template), np.full((5, 5), 0.003)
    moved = template @ _rotation(rng).T + np.array([2.0, -1.0, 0.5])  # far from anywhere it was
    ghosts = moved[rng.integers(0, 5, 6)] + rng.uniform(-0.15, 0.15, (6, 3))
    points = np.vstack([ghosts, moved])  # the body's markers are points 6..10
    order = rng.permutation(len(points))
    points = points[order]
    truth = np.argsort(order)[6:]
    nothing = np.full((5, 3), np.nan)
    assert np.array_equal(reacquire_body(points, nothing, mean, std), truth)  # no anchor at all
    anchored = nothing.copy()
    anchored[[0, 3]] = moved[[0, 3]]  # two markers already labelled
    pick = reacquire_body(points, anchored, mean, std)
    assert np.array_equal(pick[[1, 2, 4]], truth[[1, 2, 4]]) and (pick[[0, 3]] == -1).all()
    assert (reacquire_body(ghosts, nothing, mean, std) == -1).all()  # ghosts alone never make a body


def test_a_body_hidden_for_a_second_while_it_moves_is_reacquired():
    """The whole body vanishes for 1 s (longer than the 50-frame window) and comes back 0.5 m from where it
    left. Before issue 14 its labels stayed LOST for good: the gate sat where the body vanished."""
    rng = np.random.default_rng(2)
    pos, subjects = _walking_scene(rng, 360)
    labeler = OnlineLabeler(LabelingConfig(train_frames=60, accel_std_floor_mps2=2.0))
    labeler.train(pos[:60], subjects, FPS)
    hidden = np.arange(5, 10)
    back = None
    for t in range(60, 360):
        keep = np.setdiff1d(np.arange(15), hidden) if 120 <= t < 240 else np.arange(15)
        perm = rng.permutation(keep)
        result = labeler.step(pos[t, perm] + rng.normal(0, 0.0005, (len(perm), 3)))
        got = np.where(result.label_point >= 0, perm[np.maximum(result.label_point, 0)], -1)
        if 120 <= t < 240:
            assert (got[hidden] == -1).all()
        if t >= 240 and back is None and np.array_equal(got[hidden], hidden):
            back = t
    assert back is not None and back - 240 <= 2  # found again within two frames
    assert np.array_equal(got, np.arange(15))


def test_a_whole_subject_hidden_for_a_second_is_reacquired_body_by_body():
    """Every marker of the subject vanishes for 1 s while it walks 0.5 m on; each body is then found again from
    no anchor at all, by its shape, among the points of the returning subject and ghosts."""
    rng = np.random.default_rng(7)
    pos, subjects = _walking_scene(rng, 330)
    labeler = OnlineLabeler(LabelingConfig(train_frames=60, accel_std_floor_mps2=2.0))
    labeler.train(pos[:60], subjects, FPS)
    back = None
    for t in range(60, 330):
        if 120 <= t < 240:
            cloud = rng.uniform(-0.5, 0.5, (3, 3)) + pos[t].mean(axis=0)  # only ghosts while the subject is gone
        else:
            cloud = pos[t] + rng.normal(0, 0.0005, pos[t].shape)
        perm = rng.permutation(len(cloud))
        result = labeler.step(cloud[perm])
        if t < 240:
            continue
        got = np.where(result.label_point >= 0, perm[np.maximum(result.label_point, 0)], -1)
        if back is None and np.array_equal(got, np.arange(15)):
            back = t
    assert back is not None and back - 240 <= 2
    assert np.array_equal(got, np.arange(15))


def _symmetric_head_scene(rng, frames, velocity_mps, spin_radps=0.0):
    """Three rigid bodies; the middle one is a left/right symmetric near-planar quad (a head's four markers), so
    pair distances alone cannot tell its mirror image from it. spin_radps: the first (asymmetric) body also
    turns steadily about the vertical at this rate."""
    quad = np.array([[-0.08, 0.05, 0.0], [0.08, 0.05, 0.0], [-0.07, -0.06, 0.0], [0.07, -0.06, 0.0]])
    local = [rng.uniform(-0.1, 0.1, (5, 3)), quad, rng.uniform(-0.1, 0.1, (5, 3))]
    offsets = np.array([[0.0, 0, 1.0], [0.0, 0.35, 1.6], [0.0, 0.7, 1.0]])
    t = np.arange(frames) / FPS
    pos = []
    for b in range(3):
        ang = 0.4 * np.sin(0.9 * t + b) + (spin_radps * t if b == 0 else 0.0)
        c, s = np.cos(ang), np.sin(ang)
        rot = np.stack([np.stack([c, -s, 0 * c], -1), np.stack([s, c, 0 * c], -1),
                        np.stack([0 * c, 0 * c, 1 + 0 * c], -1)], -2)
        pos.append(np.einsum("fij,nj->fni", rot, local[b]) + (offsets[b] + np.outer(t, velocity_mps))[:, None])
    return np.concatenate(pos, axis=1), np.zeros(14, int)


@pytest.mark.parametrize("seed", [0, 1, 3])
def test_a_symmetric_body_lost_for_half_a_second_comes_back_not_mirrored(seed):
    """The quad vanishes for 0.5 s while the subject moves on. Before the re-entry check it came back with left
    and right exchanged in 6 of 8 such runs (these seeds among them) and stayed so: Eq. 5 scores the mirror image
    the same (cmu_135_02 --degrade 2: the head mirrored from 15 s to the end of the take)."""
    rng = np.random.default_rng(seed)
    pos, subjects = _symmetric_head_scene(rng, 360, rng.uniform(-1, 1, 3) * [1, 1, 0.2])
    labeler = OnlineLabeler(LabelingConfig(train_frames=120))
    labeler.train(pos[:120], subjects, FPS, bodies=[np.arange(5), np.arange(5, 9), np.arange(9, 14)])
    quad = np.arange(5, 9)
    for t in range(120, 360):
        keep = np.setdiff1d(np.arange(14), quad) if 180 <= t < 240 else np.arange(14)
        perm = rng.permutation(keep)
        result = labeler.step(pos[t, perm] + rng.normal(0, 0.0005, (len(perm), 3)))
        got = np.where(result.label_point >= 0, perm[np.maximum(result.label_point, 0)], -1)
        if t >= 245:  # back within 5 frames, and never mirrored
            assert np.array_equal(got, np.arange(14)), (t, got[quad])


@pytest.mark.parametrize("seed", [0, 1])
def test_an_asymmetric_body_that_turned_far_while_hidden_keeps_its_true_labels(seed):
    """The re-entry check must not "untwist" a body that really turned: the asymmetric body spins at 5 rad/s and
    is hidden for 0.5 s (143°). Its true labels fit its shape; the translation-only relabelling does not."""
    rng = np.random.default_rng(seed)
    pos, subjects = _symmetric_head_scene(rng, 330, np.zeros(3), spin_radps=5.0)
    labeler = OnlineLabeler(LabelingConfig(train_frames=120))
    labeler.train(pos[:120], subjects, FPS, bodies=[np.arange(5), np.arange(5, 9), np.arange(9, 14)])
    spinning = np.arange(5)
    for t in range(120, 330):
        keep = np.setdiff1d(np.arange(14), spinning) if 180 <= t < 240 else np.arange(14)
        perm = rng.permutation(keep)
        result = labeler.step(pos[t, perm] + rng.normal(0, 0.0005, (len(perm), 3)))
        got = np.where(result.label_point >= 0, perm[np.maximum(result.label_point, 0)], -1)
        if t >= 245:
            assert np.array_equal(got, np.arange(14)), (t, got[spinning])


def test_a_lone_marker_on_a_ghost_does_not_anchor_the_search_for_its_body():
    """A body vanishes for 0.5 s and a ghost stays where its first marker was last seen. That marker's stale gate
    hands it the ghost; anchored on that one point the shape search never found the returning body (before the
    fix: 160-535 wrong label-frames in every run). Searched again without the lone anchor, the body is found."""
    for seed in range(2):
        rng = np.random.default_rng(seed)
        pos, subjects = _walking_scene(rng, 300)
        labeler = OnlineLabeler(LabelingConfig(train_frames=60))
        labeler.train(pos[:60], subjects, FPS)
        hidden, ghost = np.arange(5, 10), pos[119, 5]
        for t in range(60, 300):
            keep = np.setdiff1d(np.arange(15), hidden) if 120 <= t < 180 else np.arange(15)
            points, truth = pos[t, keep], keep
            if t >= 120:
                points, truth = np.vstack([points, ghost]), np.append(keep, -1)
            perm = rng.permutation(len(points))
            result = labeler.step(points[perm] + rng.normal(0, 0.0005, (len(perm), 3)))
            got = np.where(result.label_point >= 0, truth[perm][np.maximum(result.label_point, 0)], -1)
            if t >= 200:
                assert np.array_equal(got, np.arange(15)), (seed, t, got[hidden])


def test_recovery_is_bounded_then_the_marker_counts_as_lost():
    """A marker hidden for 1 s is RECOVERED for at most max_recovered_s, then LOST (no position reported)."""
    rng = np.random.default_rng(3)
    pos, subjects = _walking_scene(rng, 240)
    cfg = LabelingConfig(train_frames=60, accel_std_floor_mps2=2.0, max_recovered_s=0.25)
    labeler = OnlineLabeler(cfg)
    labeler.train(pos[:60], subjects, FPS)
    status = []
    for t in range(60, 240):
        keep = np.delete(np.arange(15), 7) if t >= 100 else np.arange(15)
        result = labeler.step(pos[t, keep])
        status.append(result.status[7])
        if result.status[7] == RECOVERED:
            assert np.linalg.norm(result.positions_m[7] - pos[t, 7]) < 1e-6  # rigid body: exact
    status = np.array(status[40:])
    assert (status[:30] == RECOVERED).all() and (status[31:] == LOST).all()


@pytest.mark.parametrize("per_body", [5, 3])
def test_a_swap_inside_a_body_is_undone_by_the_training_template(per_body):
    """Force a swapped track (two body-mates' filters exchanged): the next frame labels them correctly again.
    Before issue 14 Algorithm 1 kept the swap (Eq. 5 scores only the gated candidates). Three-marker bodies
    (CMU's C7 / T10 / LSHO) are repaired by trying the permutations of their points."""
    rng = np.random.default_rng(4)
    pos, subjects = _walking_scene(rng, 120, per_body=per_body)
    labeler = OnlineLabeler(LabelingConfig(train_frames=60, accel_std_floor_mps2=2.0))
    labeler.train(pos[:60], subjects, FPS)
    for t in range(60, 80):
        labeler.step(pos[t])
    internal = {int(label): i for i, label in enumerate(labeler._order)}
    a, b = internal[0], internal[1]
    labeler.kf.pos[[a, b]] = labeler.kf.pos[[b, a]]  # the tracks now follow each other's marker
    labeler.kf.vel[[a, b]] = labeler.kf.vel[[b, a]]
    result = labeler.step(pos[80])
    assert np.array_equal(result.label_point, np.arange(3 * per_body))


def test_window_keeps_the_last_statistics_of_a_pair_absent_for_longer_than_the_window():
    window = DistanceWindow(1, 2, 5, 0.0005)
    for d in (0.30, 0.31, 0.30, 0.29, 0.30):
        window.push(np.array([[[0.0, d], [d, 0.0]]]))
    mean_before, std_before = window.stats()
    for _ in range(8):  # hidden: no observation of the pair for longer than the window
        window.push(np.full((1, 2, 2), np.nan))
    mean_after, std_after = window.stats()
    assert mean_after[0, 0, 1] == mean_before[0, 0, 1] == np.mean([0.30, 0.31, 0.30, 0.29, 0.30])
    assert std_after[0, 0, 1] == std_before[0, 0, 1]


def test_bootstrap_and_baseline_accept_a_first_frame_with_missing_markers():
    """`--bootstrap` on clouthier_PronetoRun01 failed with "matrix contains invalid numeric entries": a label
    missing in frame 0 put NaN into the Hungarian cost matrix."""
    rng = np.random.default_rng(5)
    pos, _ = _walking_scene(rng, 10)
    first = pos[0].copy()
    first[3] = np.nan
    out = bootstrap_training_labels(first, [pos[t] for t in range(1, 10)])
    assert np.isnan(out[:, 3]).all()
    assert np.allclose(np.delete(out, 3, axis=1), np.delete(pos, 3, axis=1))
    assert ClosestPointTracker(np.full((4, 3), np.nan)).step(pos[1]).tolist() == [-1] * 4


def test_evaluation_scores_windows_forced_losses_and_the_baseline():
    rng = np.random.default_rng(6)
    pos, subjects = _walking_scene(rng, 600)  # 5 s: three 1.5 s windows after 60 training frames
    data = MarkerData(tuple(f"S:M{i}" for i in range(15)), pos, FPS, "walking")
    cfg = LabelingConfig(train_frames=60, accel_std_floor_mps2=2.0)
    ev, out, results = evaluate_take(data, subjects, cfg, seed=1, window_s=1.5, forced_every_s=1.5,
                                     forced_duration_s=0.25)
    assert len(ev.window_accuracy) == 3 and len(ev.baseline_window_accuracy) == 3
    assert len(ev.reacquire_s) == 3  # one forced loss per window (the last one ends before the take)
    assert all(r < 0.5 for r in ev.reacquire_s)
    assert ev.score.accuracy > 0.98 and min(ev.window_accuracy) > 0.97
    assert ev.recovered_error_mm < 5.0
    assert out.shape == pos.shape and len(results) == 600 - 60
    # forced losses: the points of the body are gone from the stream, and only for that span
    stream = degrade(pos, subjects, DegradeConfig(0.0, 0.0, 1, 0.0, 0.0, protect_frames=60), rng)
    losses = force_losses(stream, [np.arange(5, 10)], 60, FPS, every_s=1.5, duration_s=0.25)
    assert [(loss.start, loss.end) for loss in losses] == [(150, 180), (330, 360), (510, 540)]
    assert not np.isin(stream.truth[179], np.arange(5, 10)).any() and len(stream.clouds[179]) == 10
    assert len(stream.clouds[180]) == 15 and not stream.visible[179, 5:10].any() and stream.visible[180].all()


def test_reacquisition_time_counts_the_markers_the_loss_took_not_an_older_error():
    """Known answer: body {0, 1, 2} removed over frames [7, 9); marker 2 was already wrong before the loss and
    stays wrong; markers 0 and 1 are labelled correctly again 3 frames after the body returns. The old rule (every
    visible marker correct) read "never", which every later loss of that body repeated."""
    frames, first = 14, 2
    stream = degrade(np.zeros((frames, 4, 3)) + np.arange(4)[None, :, None], np.zeros(4, int),
                     DegradeConfig(0.0, 0.0, 1, 0.0, 0.0, protect_frames=frames), np.random.default_rng(0))
    (loss,) = force_losses(stream, [np.array([0, 1, 2])], first, 1.0, every_s=10.0, duration_s=2.0)
    assert (loss.start, loss.end) == (7, 9)
    picks = []
    for t in range(first, frames):
        where = {int(label): i for i, label in enumerate(stream.truth[t])}
        pick = np.array([where.get(label, -1) for label in range(4)])
        pick[2] = where.get(3, -1)  # marker 2 holds marker 3's point throughout
        if 9 <= t < 12:
            pick[[0, 1]] = pick[[1, 0]]  # swapped for the first three frames back
        picks.append(pick)
    assert reacquisition_s(loss, stream, picks, first, fps=10.0) == 0.3
    picks = [np.full(4, -1) for _ in range(first, frames)]  # nothing correct before the loss: all must be
    assert reacquisition_s(loss, stream, picks, first, fps=10.0) == float("inf")


def test_default_training_window_is_ten_seconds_at_most_half_the_take_at_least_fifty_frames():
    from engine.labeling.evaluation import default_train_frames

    assert default_train_frames(4499, 120.0) == 1200  # a long CMU take: 10 s
    assert default_train_frames(599, 50.0) == 299  # the two-player serve: half of it
    assert default_train_frames(138, 100.0) == 69
    assert default_train_frames(20, 100.0) == 50  # more than the take: the CLI refuses it as too short
