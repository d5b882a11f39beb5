"""Exact unit checks of the paper-001 building blocks (spec 001 §5 unit tests)."""
from __future__ import annotations

import numpy as np
import pytest

from engine.labeling.config import LabelingConfig
from engine.labeling.kalman import KalmanBank
from engine.labeling.labeler import LOST, OBSERVED, RECOVERED, OnlineLabeler
from engine.labeling.search import link_table, search_body
from engine.labeling.structure import DistanceWindow, choose_cluster_tau, cluster_rigid_bodies, pair_distances


def _rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_kalman_tracks_constant_velocity_exactly_and_gates_at_gamma():
    dt, v = 1 / 120, np.array([1.0, -0.5, 0.25])
    kf = KalmanBank(np.zeros((1, 3)), np.zeros((1, 3)), np.array([1e-12]), 1e-9, dt)
    kf.cov[:, 1, 1] = 1e6  # diffuse velocity prior: the track alone determines the velocity
    for t in range(1, 6):
        kf.predict()
        kf.update(np.array([0]), (v * t * dt)[None])
    kf.predict()
    assert np.linalg.norm(kf.pos[0] - v * 6 * dt) < 1e-9  # 1e-6 mm after 5 updates
    s = kf.innovation_var()[0]
    direction = np.array([1.0, 0.0, 0.0])
    inside, outside = np.sqrt(11.3 * s) * direction, np.sqrt(11.4 * s) * direction
    assert inside @ inside / s <= 11.34 < outside @ outside / s


def _body(n=6, seed=0):
    rng = np.random.default_rng(seed)
    template = rng.uniform(-0.1, 0.1, (n, 3))
    dist = pair_distances(template)
    return rng, template, dist


def test_score_table_values():
    _, template, dist = _body(4)
    std = np.full((4, 4), 0.002)
    pos = np.full((4, 2, 3), np.nan)
    pos[:, 0] = template
    pid = np.array([[0, -1], [1, -1], [2, -1], [3, -1]])
    table = link_table(pos, pid, dist, std)
    assert table[0, 0, 1, 0] == pytest.approx(1.0)
    assert table[0, 1, 1, 0] == 0.0  # the missing option contributes nothing
    moved = pos.copy()
    moved[1, 0] = template[0] + (template[1] - template[0]) * (1 + 0.002 / dist[0, 1])  # one link longer by A
    assert link_table(moved, pid, dist, std)[0, 0, 1, 0] == pytest.approx(np.exp(-0.5))
    window = DistanceWindow(1, 4, 5, sigma_min=0.0005)  # a perfectly rigid body has A = 0 ...
    for _ in range(5):
        window.push(dist[None])
    mean, floored = window.stats()
    assert np.allclose(floored, 0.0005)  # ... which the floor turns into sigma_min, so Eq. 5 stays finite
    assert np.isfinite(link_table(pos, pid, mean[0], floored[0])).all()


def test_exhaustive_search_finds_true_assignment_among_distractors_and_never_reuses_a_point():
    rng, template, dist = _body(6, seed=3)
    rot, shift = _rotation(rng), rng.normal(size=3)
    true_pts = template @ rot.T + shift
    distractors = np.repeat(true_pts, 3, axis=0) + rng.uniform(-0.02, 0.02, (18, 3))
    points = np.vstack([true_pts, distractors])
    order = rng.permutation(len(points))
    points = points[order]
    truth = np.argsort(order)[:6]  # where each true marker went
    cand = np.stack([np.argsort(np.linalg.norm(points - p, axis=1))[:4] for p in true_pts + rng.normal(0, 0.005, (6, 3))])
    pid, score, evaluated = search_body(cand, points[cand], dist, np.full((6, 6), 0.001), 10**6)
    assert np.array_equal(pid, truth)
    assert evaluated == np.prod((cand >= 0).sum(1) + 1)
    # a body whose markers all offer the same point must not take it twice
    same = np.zeros((3, 1), int)
    pid, _, _ = search_body(same, points[same], dist[:3, :3], np.full((3, 3), 0.001), 100)
    assert (pid >= 0).sum() <= 1


def test_one_missing_marker_scores_the_remaining_links():
    _, template, dist = _body(5)
    cand = np.array([[0], [1], [2], [3], [-1]])
    pts = np.vstack([template[:4], np.full((1, 3), np.nan)])
    _, score, _ = search_body(cand, pts[cand], dist, np.full((5, 5), 0.001), 100)
    n_links = 10
    assert score == pytest.approx((n_links - 4) / n_links, abs=1e-12)


def test_clustering_recovers_rigid_groups():
    rng = np.random.default_rng(5)
    frames, groups = 60, [np.arange(0, 4), np.arange(4, 9), np.arange(9, 12)]
    pos = np.zeros((frames, 12, 3))
    for g in groups:  # each group moves rigidly with its own random rotation per frame
        local = rng.uniform(-0.1, 0.1, (len(g), 3))
        for t in range(frames):
            pos[t, g] = local @ _rotation(rng).T + rng.normal(size=3)
    std = np.std(pair_distances(pos), axis=0)
    bodies = cluster_rigid_bodies(std, 0.001)
    assert [list(b) for b in bodies] == [list(g) for g in groups]


def test_window_matches_numpy_over_last_t_valid_frames():
    rng = np.random.default_rng(6)
    window = DistanceWindow(1, 3, 5, 0.0)
    history = rng.uniform(0.1, 0.3, (12, 1, 3, 3))
    history[7, 0, 0, 1] = np.nan  # a pair not observed together in frame 7 does not enter
    for frame in history:
        window.push(frame)
    mean, std = window.stats()
    last = history[-5:, 0, 0, 1]
    assert mean[0, 0, 1] == pytest.approx(np.nanmean(last), abs=1e-12)
    assert std[0, 0, 1] == pytest.approx(np.nanstd(last), abs=1e-9)


def _rigid_scene(rng, frames=80, fps=120.0):
    """Two subjects of two rigid 4-marker bodies each, translating and slowly rotating, 1 m apart."""
    local = rng.uniform(-0.08, 0.08, (4, 4, 3))
    centres = np.array([[0, 0, 1.0], [0.3, 0, 1.0], [1.0, 0, 1.0], [1.3, 0, 1.0]])
    pos = np.zeros((frames, 16, 3))
    t = np.arange(frames) / fps
    for b in range(4):
        ang = 0.6 * t + b
        rot = np.stack([np.stack([np.cos(ang), -np.sin(ang), 0 * ang], -1),
                        np.stack([np.sin(ang), np.cos(ang), 0 * ang], -1),
                        np.stack([0 * ang, 0 * ang, 1 + 0 * ang], -1)], -2)
        pos[:, 4 * b : 4 * b + 4] = np.einsum("fij,nj->fni", rot, local[b]) + (centres[b] + np.outer(t, [0.4, 0.1, 0]))[:, None]
    return pos, np.repeat([0, 0, 1, 1], 4), fps


@pytest.mark.parametrize("recovery, tol_m", [("offsets", 0.01), ("kabsch", 1e-6)])
def test_online_labels_rigid_scene_and_recovers_a_missing_marker(recovery, tol_m):
    rng = np.random.default_rng(7)
    pos, subjects, fps = _rigid_scene(rng)
    cfg = LabelingConfig(train_frames=30, recovery=recovery, accel_std_floor_mps2=2.0)
    labeler = OnlineLabeler(cfg)
    labeler.train(pos[:30], subjects, fps)
    assert sorted(len(b) for b in labeler.bodies) == [4, 4, 4, 4]
    for t in range(30, 80):
        keep = np.arange(16) if t < 50 else np.delete(np.arange(16), 5)  # marker 5 hidden for 30 frames
        perm = rng.permutation(keep)
        result = labeler.step(pos[t, perm])
        assert np.array_equal(perm[result.label_point[keep]], keep)
        if t >= 50:
            assert result.status[5] == RECOVERED and (result.status[keep] == OBSERVED).all()
            assert np.linalg.norm(result.positions_m[5] - pos[t, 5]) < tol_m


def test_training_frames_with_holes_seed_from_where_each_marker_is_seen():
    """Issue 14: clouthier_PronetoRun01 was refused because a marker was missing in the last training frame.
    A marker missing at the end of training starts from its last sighting; one never seen in training is
    never given a point (it cannot be learned) and never makes anything fail."""
    rng = np.random.default_rng(8)
    pos, subjects, fps = _rigid_scene(rng)
    holed = pos[:30].copy()
    holed[20:, 2] = np.nan  # marker 2 hidden for the last 10 training frames
    holed[:, 9] = np.nan  # marker 9 never seen in training
    labeler = OnlineLabeler(LabelingConfig(train_frames=30, accel_std_floor_mps2=2.0))
    labeler.train(holed, subjects, fps)
    for t in range(30, 60):
        perm = rng.permutation(16)
        result = labeler.step(pos[t, perm])
        got = np.where(result.label_point >= 0, perm[np.maximum(result.label_point, 0)], -1)
        assert got[9] == -1 and result.status[9] == LOST
        keep = np.delete(np.arange(16), 9)
        if t >= 35:  # a few frames to pull marker 2's filter from its stale position
            assert np.array_equal(got[keep], keep)
    with pytest.raises(ValueError, match="partition"):
        OnlineLabeler().train(pos[:30], subjects, fps, bodies=[np.arange(8)])


def test_tau_search_picks_a_threshold_giving_bodies_of_three_to_eight():
    """Rigid groups whose within-group std is ~5 mm: a fixed 3 mm threshold leaves singletons, the search finds
    a threshold that restores the groups."""
    rng = np.random.default_rng(11)
    n, groups = 12, [range(0, 4), range(4, 8), range(8, 12)]
    std = np.full((n, n), 0.05)
    for g in groups:
        for i in g:
            for j in g:
                std[i, j] = 0.004 + 0.002 * rng.random()
    std = np.minimum(std, std.T)
    np.fill_diagonal(std, 0.0)
    assert choose_cluster_tau(std, np.array([0.003])) == 0.003
    tau = choose_cluster_tau(std, np.geomspace(0.003, 0.03, 12))
    assert [list(b) for b in cluster_rigid_bodies(std, tau)] == [list(g) for g in groups]


def test_greedy_loop_gives_a_contested_point_to_the_body_it_fits():
    """Two subjects' bodies both gate the same point; it fits body A exactly and body B poorly. A takes it and B
    reports that marker missing, whichever body comes first in the label order."""
    rng = np.random.default_rng(12)
    a = rng.uniform(-0.05, 0.05, (3, 3))
    b = rng.uniform(-0.05, 0.05, (3, 3)) + np.array([0.12, 0.0, 0.0])
    for first in ("a", "b"):
        frames = np.stack([np.vstack([a, b] if first == "a" else [b, a])] * 20)
        subjects = np.repeat([0, 1], 3)
        labeler = OnlineLabeler(LabelingConfig(train_frames=20, max_candidates=6, gate_chi2=1e6))
        labeler.train(frames, subjects, 120.0)
        a_idx, b_idx = (np.arange(3), np.arange(3, 6)) if first == "a" else (np.arange(3, 6), np.arange(3))
        # frame: body A complete; body B's marker 0 hidden, but A's marker 0 lies inside B's gate
        points = np.vstack([a, b[1:]])
        result = labeler.step(points)
        assert result.label_point[a_idx[0]] == 0  # A keeps its point
        assert result.label_point[b_idx[0]] == -1  # B does not steal it
        assert np.array_equal(result.label_point[b_idx[1:]], [3, 4])


def test_label_cli_reports_bad_input_naming_the_file(tmp_path, capsys):
    from engine.labeling.cli import main

    missing = tmp_path / "nothing.c3d"
    assert main([str(missing), "-o", str(tmp_path / "out.c3d")]) == 2
    assert "nothing.c3d" in capsys.readouterr().err
    garbage = tmp_path / "garbage.c3d"
    garbage.write_bytes(b"\x00" * 64)
    assert main([str(garbage), "-o", str(tmp_path / "out.c3d")]) == 2
    assert "garbage.c3d" in capsys.readouterr().err


def test_labelled_c3d_round_trips_with_missing_samples(tmp_path):
    from engine.labeling.c3d_io import write_c3d
    from engine.mocap import MarkerData, read_c3d

    pos = np.random.default_rng(13).uniform(-1, 1, (10, 4, 3))
    pos[3:6, 2] = np.nan
    write_c3d(tmp_path / "x.c3d", MarkerData(("S:A", "S:B", "S:C", "S:D"), pos, 120.0))
    back = read_c3d(tmp_path / "x.c3d")
    assert back.labels == ("S:A", "S:B", "S:C", "S:D") and back.fps == 120.0
    assert np.array_equal(np.isnan(back.positions_m), np.isnan(pos))
    assert np.allclose(back.positions_m[~np.isnan(pos)], pos[~np.isnan(pos)], atol=1e-6)


def test_a_perfectly_rigid_large_group_is_split_to_the_maximum_size():
    bodies = cluster_rigid_bodies(np.zeros((12, 12)), 0.003, min_body=3, max_body=8)
    assert sorted(len(b) for b in bodies) == [6, 6]
    assert sorted(np.concatenate(bodies).tolist()) == list(range(12))
