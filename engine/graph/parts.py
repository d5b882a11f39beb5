"""What a motion graph is built from: the node and edge kinds, and `GraphParts`, the growing arrays the graph
build (`graph.build_from_clips`), speed variations (`msv`) and interpolated motions (`interpolate`) append to
before `graph.assemble` turns them into a `MotionGraph`. Its own module so those steps depend on it, not on each
other."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

NODE_ORIGINAL, NODE_SLOW, NODE_INTERP = 0, 1, 2
EDGE_NATURAL, EDGE_TRANSITION, EDGE_SPEEDUP, EDGE_SLOWDOWN, EDGE_INTERP = 0, 1, 2, 3, 4
EDGE_KIND_NAMES = ("natural", "transition", "speed-up", "slow-down", "interpolated")


@dataclass
class GraphParts:
    """Growing lists of node/edge/metadata arrays; MSV and interpolation append to it before assembly."""

    node: dict[str, list[np.ndarray]] = field(default_factory=dict)
    edge: dict[str, list[np.ndarray]] = field(default_factory=dict)
    meta: dict[str, list[np.ndarray]] = field(default_factory=dict)
    n_nodes: int = 0
    n_meta: int = 0

    def add_nodes(self, **arrays: np.ndarray) -> np.ndarray:
        """Append nodes (each array's first axis = the new nodes); returns their ids."""
        n = len(next(iter(arrays.values())))
        for key, arr in arrays.items():
            self.node.setdefault(key, []).append(arr)
        ids = np.arange(self.n_nodes, self.n_nodes + n)
        self.n_nodes += n
        return ids

    def add_meta(self, acc_g: np.ndarray, dheading_rad: np.ndarray, dpos_m: np.ndarray) -> np.ndarray:
        """Append metadata rows; returns their row ids."""
        for key, arr in (("acc", acc_g), ("dheading", dheading_rad), ("dpos", dpos_m)):
            self.meta.setdefault(key, []).append(np.asarray(arr))
        ids = np.arange(self.n_meta, self.n_meta + len(dheading_rad))
        self.n_meta += len(dheading_rad)
        return ids

    def add_edges(self, src: np.ndarray, dst: np.ndarray, kind: int, meta: np.ndarray) -> None:
        for key, arr in (("src", src), ("dst", dst), ("meta", meta)):
            self.edge.setdefault(key, []).append(np.asarray(arr, dtype=np.int64))
        self.edge.setdefault("kind", []).append(np.full(len(src), kind, dtype=np.int8))
