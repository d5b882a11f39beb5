"""Online lazy neighbourhood graph (OLNG, Tautges et al. 2011 §4; spec A2.4).

The last M input frames each contribute a column of K database frames (their nearest neighbours, sorted by
database index). A path is a strictly monotone run of nodes through those columns whose database index advances
like a time-warped copy of the input: between columns c and c' = c + dc (1 <= dc <= dc_max) the index advances by
dn with ceil(dc / w) <= dn <= w * dc (w = max_warp, so at most 2x faster or slower), and never across clips.

Only K paths are kept: for each node of the newest column, the cheapest path ending there.
Cost (window-normalised, spec A2.4): every window column contributes the node distance if the path has a node
there, a skip cost if the path jumps over it (see `_skip_costs`), and otherwise (before the path starts) the
column's "miss" cost mu_c = its K-th neighbour distance;
divided by min(M, t). Each path stores its per-column contributions in ring slots (column c -> slot c mod M),
so sliding the window is exact: the slot of the column that leaves is simply overwritten.

Everything per frame is vectorised over the K nodes: predecessor candidates come from np.searchsorted on the
sorted predecessor column, at most w*dc of them per node.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from engine.olng.config import NeighbourhoodGraphConfig


@dataclass
class _Column:
    idx: np.ndarray      # (K,) sorted database indices
    rows: np.ndarray     # (K, M) per-slot cost contributions of the best path ending at each node
    sums: np.ndarray     # (K,) row sums
    start: np.ndarray    # (K,) input column where each path starts
    nodes: np.ndarray    # (K,) number of nodes on each path
    query: np.ndarray | None  # the input reading of this column


class OnlineLazyNeighbourhoodGraph:
    """Streaming OLNG over a database whose frames belong to clips `clip_id` (N,)."""

    def __init__(self, clip_id: np.ndarray, config: NeighbourhoodGraphConfig = NeighbourhoodGraphConfig(),
                 readings: np.ndarray | None = None) -> None:
        """readings (N, D): the database readings; needed for skip_cost='held' (then push() needs the query)."""
        if config.window < 1 or config.max_column_step < 1 or config.max_warp < 1:
            raise ValueError("window, max_column_step and max_warp must be >= 1")
        if config.skip_cost not in {"held", "miss"}:
            raise ValueError(f"skip_cost must be 'held' or 'miss', not {config.skip_cost!r}")
        if config.skip_cost == "held" and readings is None:
            raise ValueError("skip_cost='held' needs the database readings")
        self.readings = readings
        self.clip_id = np.asarray(clip_id)
        self.config = config
        self.columns_pushed = 0
        self._mu_slots = np.zeros(config.window)
        self._history: deque[_Column] = deque(maxlen=config.max_column_step)

    # ------------------------------------------------------------------ update
    def _skip_costs(self, prev: _Column, dc: int) -> np.ndarray:
        """(K_prev, dc-1) cost of the columns a dc-step skips, per predecessor node (slot order t-1, t-2, ...).

        'miss': skip_penalty * mu of the skipped column (spec A2.4). 'held': skip_penalty * distance of the skipped
        column's reading to the predecessor's own database frame, i.e. priced as if the database had paused there;
        with 'miss' a slower-than-database performer pays a K-th-neighbour distance per skip and the best path runs
        ahead instead (spec A6.1), which breaks +-1 frame tracking at 0.6x."""
        skipped = [self._history[-k] for k in range(1, dc)]
        if not skipped:
            return np.zeros((len(prev.idx), 0))
        if self.config.skip_cost == "miss":
            mus = np.array([self._mu_slots[(self.columns_pushed - k) % self.config.window] for k in range(1, dc)])
            return np.broadcast_to(self.config.skip_penalty * mus, (len(prev.idx), dc - 1))
        held = self.readings[prev.idx]
        return self.config.skip_penalty * np.stack([np.linalg.norm(held - col.query, axis=1) for col in skipped], axis=1)

    def push(self, idx: np.ndarray, dist: np.ndarray, query: np.ndarray | None = None) -> None:
        """Add the column for a new input frame: its K nearest database indices (ascending, unique), their
        distances, and the query reading itself (needed for skip_cost='held')."""
        if self.config.skip_cost == "held" and query is None:
            raise ValueError("skip_cost='held' needs the query reading in push()")
        idx = np.asarray(idx)
        dist = np.asarray(dist, dtype=float)
        if idx.ndim != 1 or idx.shape != dist.shape:
            raise ValueError("idx and dist must be 1-D arrays of the same length")
        if len(idx) > 1 and np.any(np.diff(idx) <= 0):
            raise ValueError("column indices must be strictly ascending (sort the kNN result by database index)")
        m = self.config.window
        t = self.columns_pushed
        slot = t % m
        mu_t = float(dist.max()) if len(dist) else 0.0
        self._mu_slots[slot] = mu_t
        count = len(idx)

        # fallback: a new path starting at each node (all earlier window columns missed)
        best_sum = self._mu_slots.sum() - mu_t + dist
        best_dc = np.zeros(count, dtype=int)
        best_pos = np.zeros(count, dtype=int)
        my_clip = self.clip_id[idx]
        w = self.config.max_warp
        for dc in range(1, len(self._history) + 1):
            prev = self._history[-dc]
            if len(prev.idx) == 0:
                continue
            replaced = [(t - k) % m for k in range(dc)]          # slots rewritten by this step
            skip = self._skip_costs(prev, dc)
            adjusted = prev.sums - prev.rows[:, replaced].sum(axis=1) + skip.sum(axis=1)
            lo = np.searchsorted(prev.idx, idx - w * dc, side="left")
            hi = np.searchsorted(prev.idx, idx - math.ceil(dc / w), side="right")
            width = w * dc - math.ceil(dc / w) + 1
            pos = lo[:, None] + np.arange(width)
            valid = pos < hi[:, None]
            pos = np.minimum(pos, len(prev.idx) - 1)
            valid &= self.clip_id[prev.idx[pos]] == my_clip[:, None]
            cand = np.where(valid, adjusted[pos] + dist[:, None], np.inf)
            arg = np.argmin(cand, axis=1)
            cand_best = cand[np.arange(count), arg]
            # ties: extending beats starting afresh (longer paths preferred), a plain step beats a skip
            better = np.where(best_dc == 0, cand_best <= best_sum, cand_best < best_sum) & np.isfinite(cand_best)
            best_sum = np.where(better, cand_best, best_sum)
            best_dc = np.where(better, dc, best_dc)
            best_pos = np.where(better, pos[np.arange(count), arg], best_pos)

        rows = np.broadcast_to(self._mu_slots, (count, m)).copy()
        start = np.full(count, t)
        nodes = np.ones(count, dtype=int)
        for dc in range(1, len(self._history) + 1):
            chosen = best_dc == dc
            if not chosen.any():
                continue
            prev = self._history[-dc]
            src = best_pos[chosen]
            block = prev.rows[src]
            block[:, [(t - k) % m for k in range(1, dc)]] = self._skip_costs(prev, dc)[src]
            rows[chosen] = block
            start[chosen] = prev.start[src]
            nodes[chosen] = prev.nodes[src] + 1
        rows[:, slot] = dist
        self._history.append(_Column(idx=idx, rows=rows, sums=rows.sum(axis=1), start=start, nodes=nodes, query=query))
        self.columns_pushed += 1

    # ------------------------------------------------------------------ queries
    @property
    def current(self) -> _Column:
        if not self._history:
            raise RuntimeError("no column pushed yet")
        return self._history[-1]

    @property
    def costs(self) -> np.ndarray:
        """Window-normalised cost of the K current paths (one per node of the newest column)."""
        return self.current.sums / min(self.config.window, self.columns_pushed)

    def best(self, count: int) -> tuple[np.ndarray, np.ndarray]:
        """The `count` cheapest current paths: (database index of each path's last node, its cost), cheapest first."""
        costs = self.costs
        count = min(count, len(costs))
        part = np.argpartition(costs, count - 1)[:count] if count < len(costs) else np.arange(len(costs))
        order = part[np.argsort(costs[part], kind="stable")]
        return self.current.idx[order], costs[order]

    def span_columns(self) -> np.ndarray:
        """Window columns covered by each current path (from its first node inside the window to the newest column)."""
        return np.minimum(self.columns_pushed - self.current.start, self.config.window)


def path_weights(costs: np.ndarray) -> np.ndarray:
    """Eq. 1: w_i = (max C - c_i) / sum_j (max C - c_j); the worst path gets 0, equal costs fall back to uniform."""
    costs = np.asarray(costs, dtype=float)
    gain = costs.max() - costs
    total = gain.sum()
    if total <= 0.0:
        return np.full(len(costs), 1.0 / len(costs))
    return gain / total
