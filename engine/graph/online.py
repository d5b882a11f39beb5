"""Online synthesis: a fixed-lag Viterbi decoder (sensor streams reach the graph rate through `engine.stream`).

At sample t the decoder advances the lattice (O(E)), then decides sample t - L by back-tracing L steps from the
currently best node: the latency is L samples and the memory L lattice columns (older ones are dropped).
With L >= the sequence length nothing is decided before `flush()`, which back-traces the whole lattice exactly
as the batch search does -- the two are the same computation.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .graph import MotionGraph
from .poses import world_joint_positions
from .viterbi import DEFAULT_KERNEL, PRUNE_EVERY, SearchWeights, ViterbiLattice


@dataclass(frozen=True)
class EmittedPose:
    """The decided pose of sample `t`: graph node, joint positions (J, 3) m in the world frame, and the
    path's root ground position (x, z) m and heading rad."""

    t: int
    node: int
    joint_positions_m: np.ndarray
    ground_m: np.ndarray
    heading_rad: float


class FixedLagSynthesizer:
    """Push one synchronised sample at the graph rate, get back the poses decided `lag_s` seconds ago."""

    def __init__(self, graph: MotionGraph, lag_s: float, weights: SearchWeights = SearchWeights(),
                 sensor_indices: tuple[int, ...] | None = None, prune_every: int = PRUNE_EVERY,
                 kernel: str = DEFAULT_KERNEL) -> None:
        if lag_s < 0:
            raise ValueError("lag must be non-negative")
        self.graph = graph
        self.lag = int(round(lag_s * graph.config.fps))
        self.lattice = ViterbiLattice(graph, weights, sensor_indices, prune_every, kernel)
        self.next_emit = 0  # first sample not yet emitted
        self._last: tuple[complex, float, int] | None = None  # (ground, heading, node) of the last emitted sample

    def push(self, acc_g: np.ndarray | None, pos_m: np.ndarray | None = None, heading_rad: float | None = None,
             penalty: np.ndarray | None = None) -> list[EmittedPose]:
        """Consume sample t (acc (S, 3) g, optional ground position (2,) m and heading rad; `penalty` = optional
        per-node broken-constraint count for this sample); returns the pose of sample t - L once t >= L."""
        self.lattice.step(acc_g, pos_m, heading_rad, penalty)
        t = self.lattice.t
        if t - self.lag < self.next_emit:
            return []
        return self._emit(t - self.lag, t - self.lag)

    def flush(self) -> list[EmittedPose]:
        """End of input: emit every sample not yet decided, along the final best path."""
        if self.lattice.t < self.next_emit:
            return []
        self.lattice.prune()
        return self._emit(self.next_emit, self.lattice.t)

    def _start_after_last_emitted(self, node: int, edge: int) -> tuple[complex, float] | None:
        """Markov (accelerometer-only) search: the global state of the first sample to emit, continuing from the
        last emitted one -- along the arriving edge if it leaves the last emitted node, else with the node's
        own natural step (the decoder changed its mind; the pose jumps but the root path stays continuous)."""
        if self._last is None:
            return None  # first sample: the lattice's start state
        ground, heading, prev = self._last
        g = self.graph
        row = g.edge_meta[edge] if edge >= 0 and g.edge_src[edge] == prev else g.node_arrival[node]
        d = complex(*g.meta_dpos_m[row])
        return ground + d * np.exp(-1j * heading), heading + g.meta_dheading_rad[row]

    def _emit(self, first: int, last: int) -> list[EmittedPose]:
        lat = self.lattice
        best = lat.best_node()
        nodes, edges = lat.backtrace(best, lat.t - first)
        start = None if lat.track_global else self._start_after_last_emitted(int(nodes[0]), int(edges[0]))
        ground, heading = lat.global_states(best, edges, start)
        k = last - first + 1
        nodes, ground, heading = nodes[:k], ground[:k], heading[:k]
        joints = world_joint_positions(self.graph, nodes, ground, heading)
        self.next_emit = last + 1
        self._last = (complex(*ground[-1]), float(heading[-1]), int(nodes[-1]))
        lat.drop_before(self.next_emit)
        return [EmittedPose(first + i, int(nodes[i]), joints[i], ground[i], float(heading[i])) for i in range(k)]
