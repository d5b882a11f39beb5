"""Edge layout for the search's per-node minimum over incoming edges.

`np.minimum.reduceat` over dst-sorted edges is the textbook form, but its per-segment overhead dominates
when most segments hold 1-3 edges (6 ms for 330k edges here, more than all the cost arithmetic). So the
search reorders edges by the in-degree d of their destination: all nodes with in-degree d form one block
stored slot-major, shape (d, n_d), where row k holds every node's k-th incoming edge. The minimum and the
arg-minimum then come from d - 1 whole-row comparisons (no per-node work), or `argmin(axis=0)` for the few
high-degree blocks. Ties keep the lowest slot, i.e. the incoming edge with the lowest source id (the same
choice as the first-index reduceat argmin).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SMALL_DEGREE = 8  # blocks up to this in-degree use row comparisons; larger ones argmin(axis=0)


@dataclass(frozen=True)
class Block:
    offset: int  # first layout position of the block
    degree: int
    nodes: slice  # slice of `EdgeLayout.nodes` this block fills
    count: int  # nodes in the block


class EdgeLayout:
    """`order[i]` = graph edge id at layout position i; `nodes` = destination of each block column."""

    def __init__(self, edge_dst: np.ndarray, n_nodes: int) -> None:
        dst = np.asarray(edge_dst, dtype=np.int64)
        indeg = np.bincount(dst, minlength=n_nodes)
        starts = np.r_[0, np.cumsum(indeg)[:-1]]  # edges are sorted by dst: node n's edges start here
        order, nodes, blocks = [], [], []
        offset = filled = 0
        for d in np.unique(indeg[indeg > 0]):
            group = np.flatnonzero(indeg == d)
            slots = starts[group][None, :] + np.arange(d)[:, None]  # (d, n_d) edge ids, slot-major
            order.append(slots.reshape(-1))
            nodes.append(group)
            blocks.append(Block(offset, int(d), slice(filled, filled + len(group)), len(group)))
            offset += int(d) * len(group)
            filled += len(group)
        self.order = np.concatenate(order) if order else np.zeros(0, dtype=np.int64)
        self.nodes = np.concatenate(nodes) if nodes else np.zeros(0, dtype=np.int64)
        self.blocks = blocks
        self._cols = np.arange(max((b.count for b in blocks), default=0))

    def argmin(self, cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(minimum per node of `self.nodes`, layout position of the winning edge) for layout-ordered `cost`."""
        best = np.empty(len(self.nodes), dtype=cost.dtype)
        win = np.empty(len(self.nodes), dtype=np.int64)
        for b in self.blocks:
            blk = cost[b.offset:b.offset + b.degree * b.count].reshape(b.degree, b.count)
            cols = self._cols[:b.count]
            if b.degree <= SMALL_DEGREE:
                m = blk[0].copy()
                slot = np.zeros(b.count, dtype=np.int64)
                for k in range(1, b.degree):
                    lt = blk[k] < m
                    np.copyto(m, blk[k], where=lt)
                    np.copyto(slot, k, where=lt)
            else:
                slot = blk.argmin(axis=0)
                m = blk[slot, cols]
            best[b.nodes] = m
            win[b.nodes] = b.offset + slot * b.count + cols
        return best, win

    def block_min(self, values: np.ndarray) -> np.ndarray:
        """Per-node minimum of layout-ordered `values` (used for the broken-constraint counts)."""
        out = np.empty(len(self.nodes), dtype=values.dtype)
        for b in self.blocks:
            out[b.nodes] = values[b.offset:b.offset + b.degree * b.count].reshape(b.degree, b.count).min(axis=0)
        return out

    def broadcast(self, per_node: np.ndarray) -> np.ndarray:
        """Layout-ordered copy of a per-node (of `self.nodes`) value, one per incoming edge."""
        out = []
        for b in self.blocks:
            out.append(np.tile(per_node[b.nodes], b.degree))
        return np.concatenate(out) if out else np.zeros(0, dtype=per_node.dtype)
