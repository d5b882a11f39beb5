"""kNN, OLNG and Eq. 1 weights against brute force and exact synthetic answers (spec A5.3-A5.5)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from engine.olng.config import NeighbourhoodGraphConfig
from engine.olng.graph import OnlineLazyNeighbourhoodGraph, path_weights


def test_kdtree_neighbours_equal_brute_force():
    rng = np.random.default_rng(0)
    data = rng.normal(size=(10_000, 12))
    query = rng.normal(size=12)
    dist, idx = cKDTree(data, leafsize=32).query(query, k=64, workers=1)
    brute = np.linalg.norm(data - query, axis=1)
    order = np.argsort(brute)[:64]
    np.testing.assert_array_equal(idx, order)
    np.testing.assert_allclose(dist, brute[order], rtol=1e-12)


def _brute_best_costs(columns, clip_id, window, dc_max, warp, readings, skip_cost):
    """Minimum window cost of any admissible path ending at each node of the newest column, by enumeration.

    columns: list of (idx, dist, query). Skipped columns cost mu ('miss') or |query - reading of the node before
    the skip| ('held')."""
    t = len(columns) - 1
    first = max(0, t - window + 1)
    mus = {c: columns[c][1].max() for c in range(first, t + 1)}
    denom = min(window, t + 1)
    best = np.full(len(columns[t][0]), np.inf)

    def extend(path):  # path = list of (column, position) ending at the newest column, grown backwards
        c_last, p_last = path[0]
        yield path
        if c_last < first:   # one node before the window only prices the skip into it
            return
        for dc in range(1, dc_max + 1):
            c = c_last - dc
            if c < max(0, first - dc_max + 1):
                break
            n_last = columns[c_last][0][p_last]
            for p, n in enumerate(columns[c][0]):
                if math.ceil(dc / warp) <= n_last - n <= warp * dc and clip_id[n] == clip_id[n_last]:
                    yield from extend([(c, p)] + path)

    for j in range(len(columns[t][0])):
        for path in extend([(t, j)]):
            on = {c: columns[c][1][p] for c, p in path}
            for (c0, p0), (c1, _) in zip(path[:-1], path[1:]):
                for c in range(c0 + 1, c1):
                    held = np.linalg.norm(columns[c][2] - readings[columns[c0][0][p0]])
                    on[c] = held if skip_cost == "held" else mus[c]
            cost = sum(on.get(c, mus[c]) for c in range(first, t + 1)) / denom
            best[j] = min(best[j], cost)
    return best


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("skip_cost", ["held", "miss"])
def test_olng_matches_brute_force_dp(seed, skip_cost):
    """Before the window slides the greedy update is an exact DP; afterwards it is never better than the optimum."""
    rng = np.random.default_rng(seed)
    n, k, window = 40, 8, 5
    clip_id = (np.arange(n) >= 23).astype(int)
    readings = rng.normal(size=(n, 3))
    graph = OnlineLazyNeighbourhoodGraph(clip_id, NeighbourhoodGraphConfig(k_neighbours=k, window=window, skip_cost=skip_cost), readings)
    columns = []
    for t in range(9):
        centre = 3 + 2 * t
        pool = np.arange(max(0, centre - 8), min(n, centre + 8))
        idx = np.sort(rng.choice(pool, size=k, replace=False))
        query = rng.normal(size=3)
        dist = np.linalg.norm(readings[idx] - query, axis=1)
        columns.append((idx, dist, query))
        graph.push(idx, dist, query)
        brute = _brute_best_costs(columns, clip_id, window, 2, 2, readings, skip_cost)
        if t < window:
            np.testing.assert_allclose(graph.costs, brute, rtol=1e-12)
        else:
            assert np.all(graph.costs >= brute - 1e-12)


def _warp_stream(speed, frames=60, n=400, seed=7):
    """Database = one smooth random 12-D clip; query = the same signal read at `speed` x the database rate."""
    rng = np.random.default_rng(seed)
    base = np.cumsum(rng.normal(size=(n, 12)), axis=0)
    kernel = np.exp(-0.5 * (np.arange(-6, 7) / 2.5) ** 2)
    signal = np.stack([np.convolve(base[:, d], kernel / kernel.sum(), mode="same") for d in range(12)], 1)
    true_index = 20 + speed * np.arange(frames)
    grid = np.arange(n)
    query = np.stack([np.interp(true_index, grid, signal[:, d]) for d in range(12)], 1)
    return signal, query, true_index


@pytest.mark.parametrize("speed", [0.6, 0.8, 1.0, 1.5, 1.9])
def test_time_warp_recovery(speed):
    signal, query, true_index = _warp_stream(speed, frames=int(40 / max(speed, 1)) + 20)
    tree = cKDTree(signal)
    graph = OnlineLazyNeighbourhoodGraph(np.zeros(len(signal), int), NeighbourhoodGraphConfig(k_neighbours=48, window=16), signal)
    for t, reading in enumerate(query):
        dist, idx = tree.query(reading, k=48)
        order = np.argsort(idx)
        graph.push(idx[order], dist[order], reading)
        nodes, _ = graph.best(1)
        best_span = graph.span_columns()[np.argmin(graph.costs)]
        if best_span >= 5:
            assert abs(nodes[0] - true_index[t]) <= 1.0 + 1e-9, (t, nodes[0], true_index[t])
    assert graph.span_columns().max() == 16  # full-length paths formed


@pytest.mark.parametrize("skip_cost", ["held", "miss"])
def test_speed_three_forms_no_full_length_path(skip_cost):
    """Warp is capped at 2x: over 16 columns a 3x input outruns any path by 16 frames, more than the 8-frame
    neighbourhood, so no path can span the window."""
    signal, query, _ = _warp_stream(3.0, frames=40, n=400)
    tree = cKDTree(signal)
    config = NeighbourhoodGraphConfig(k_neighbours=8, window=16, skip_cost=skip_cost)
    graph = OnlineLazyNeighbourhoodGraph(np.zeros(len(signal), int), config, signal)
    for reading in query:
        dist, idx = tree.query(reading, k=8)
        order = np.argsort(idx)
        graph.push(idx[order], dist[order], reading)
    assert graph.span_columns().max() < 16


def test_paths_never_cross_clip_boundaries():
    clip_id = np.array([0] * 10 + [1] * 10)
    for clips, expect_nodes in ((clip_id, 1), (np.zeros(20, int), 2)):
        graph = OnlineLazyNeighbourhoodGraph(clips, NeighbourhoodGraphConfig(k_neighbours=1, window=8, skip_cost="miss"))
        graph.push(np.array([9]), np.array([0.1]))
        graph.push(np.array([10]), np.array([0.1]))   # db step 9 -> 10 is admissible only inside one clip
        assert graph.current.nodes[0] == expect_nodes


def test_startup_has_result_at_first_column_and_rejects_unsorted():
    graph = OnlineLazyNeighbourhoodGraph(np.zeros(10, int), NeighbourhoodGraphConfig(window=4, skip_cost="miss"))
    graph.push(np.array([2, 5]), np.array([0.3, 0.1]))
    nodes, costs = graph.best(2)
    np.testing.assert_array_equal(nodes, [5, 2])
    np.testing.assert_allclose(costs, [0.1, 0.3])
    with pytest.raises(ValueError, match="ascending"):
        graph.push(np.array([5, 2]), np.array([0.1, 0.2]))


def test_no_warp_config_only_allows_unit_steps():
    graph = OnlineLazyNeighbourhoodGraph(np.zeros(30, int), NeighbourhoodGraphConfig(window=8, max_column_step=1, max_warp=1, skip_cost="miss"))
    for n in (3, 5, 7):   # 2x speed: linear search cannot follow
        graph.push(np.array([n]), np.array([0.1]))
    assert graph.current.nodes[0] == 1
    graph = OnlineLazyNeighbourhoodGraph(np.zeros(30, int), NeighbourhoodGraphConfig(window=8, skip_cost="miss"))
    for n in (3, 5, 7):
        graph.push(np.array([n]), np.array([0.1]))
    assert graph.current.nodes[0] == 3


def test_eq1_weights():
    costs = np.array([0.2, 0.5, 0.9, 0.4])
    w = path_weights(costs)
    assert w.sum() == pytest.approx(1.0)
    assert w[2] == 0.0
    assert np.all(np.diff(w[np.argsort(costs)]) <= 0)
    np.testing.assert_allclose(path_weights(np.full(5, 0.3)), 0.2)
