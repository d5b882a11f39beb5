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
from .confidence import CostHistory, CostWindow, confidence, reference_cost_per_sample
from .root_fusion import RootFuser, RootFusion
from .warp import RootWarp


@dataclass(frozen=True)
class EmittedPose:
    """The decided pose of sample `t`: graph node, joint positions (J, 3) m in the world frame, the output root's
    ground position (x, z) m and heading rad (the camera's smoothed track with root fusion, else the path's), and `confidence` in [0, 1] (confidence.py: 1 = the search costs
    what the database's own clips cost; towards 0 = the engine is lost)."""

    t: int
    node: int
    joint_positions_m: np.ndarray
    ground_m: np.ndarray
    heading_rad: float
    confidence: float = 1.0


class FixedLagSynthesizer:
    """Push one synchronised sample at the graph rate, get back the poses decided `lag_s` seconds ago.

    Each pose carries a confidence (confidence.py): the cost per sample over the `confidence_window_s` window
    centred on it (as far as the lag reaches) against `confidence_reference`, the per-sample cost of the
    database's own clips (None: measured on this graph at construction, `reference_cost_per_sample`, ~1 s on a
    100k-node graph). When the cost per sample over the last `confidence_window_s` stays above `reanchor_ratio`
    x the reference for `reanchor_after_s`, the search re-anchors (`ViterbiLattice.reanchor`: the accumulated
    costs are forgotten and every path's root is put on the camera fix) -- a lost track recovers from fresh
    evidence instead of defending a wrong history. `reanchor_ratio` = 0 never re-anchors.

    `fusion` (root_fusion.py): the output root is the camera track smoothed over the same lag, the chosen path
    supplying the root-relative pose (and the root only where the camera is absent); off = the path's own root."""

    def __init__(self, graph: MotionGraph, lag_s: float, weights: SearchWeights = SearchWeights(),
                 sensor_indices: tuple[int, ...] | None = None, prune_every: int = PRUNE_EVERY,
                 kernel: str = DEFAULT_KERNEL, warp: RootWarp = RootWarp.off(),
                 confidence_reference: float | None = None, confidence_window_s: float = 2.0,
                 reanchor_ratio: float = 4.0, reanchor_after_s: float = 3.0,
                 fusion: RootFusion = RootFusion.off()) -> None:
        if lag_s < 0:
            raise ValueError("lag must be non-negative")
        self.graph = graph
        self.lag = int(round(lag_s * graph.config.fps))
        self.lattice = ViterbiLattice(graph, weights, sensor_indices, prune_every, kernel, warp)
        self.next_emit = 0  # first sample not yet emitted
        self._last: tuple[complex, float, int] | None = None  # the path's (ground, heading, node) at the last emitted
        self._fuser = RootFuser(fusion, graph.config.fps)  # the output root (the path's own when fusion is off)
        if confidence_reference is None:
            confidence_reference = reference_cost_per_sample(graph, weights, warp, sensor_indices)
        self.confidence_reference = confidence_reference
        fps = graph.config.fps
        window = max(1, int(round(confidence_window_s * fps)))
        self._window = CostWindow(window)  # the last `window` samples: re-anchoring
        self._history = CostHistory(window)  # centred on each decided sample: its confidence
        self.reanchor_ratio = reanchor_ratio
        self._reanchor_after = max(1, int(round(reanchor_after_s * fps)))
        self._high_for = 0  # consecutive samples with the window cost above reanchor_ratio x reference
        self.reanchors: list[int] = []  # samples at which the search re-anchored

    def push(self, acc_g: np.ndarray | None, pos_m: np.ndarray | None = None, heading_rad: float | None = None,
             penalty: np.ndarray | None = None) -> list[EmittedPose]:
        """Consume sample t (acc (S, 3) g, optional ground position (2,) m and heading rad; `penalty` = optional
        per-node broken-constraint count for this sample); returns the pose of sample t - L once t >= L."""
        lat = self.lattice
        lat.step(acc_g, pos_m, heading_rad, penalty)
        self._fuser.push(pos_m, heading_rad)
        t = lat.t
        per_sample = self._window.push(lat.cost_offset)
        self._history.push(lat.cost_offset)
        high = self.reanchor_ratio > 0 and np.isfinite(per_sample) and \
            per_sample > self.reanchor_ratio * self.confidence_reference
        self._high_for = self._high_for + 1 if high else 0
        if self._high_for >= self._reanchor_after:
            lat.reanchor(pos_m, heading_rad)
            self.reanchors.append(t)
            self._high_for = 0
            self._window.clear()
        if t - self.lag < self.next_emit:
            return []
        return self._emit(t - self.lag, t - self.lag)

    def flush(self) -> list[EmittedPose]:
        """End of input: emit every sample not yet decided, along the final best path."""
        if self.lattice.t < self.next_emit:
            return []
        self.lattice.prune()
        return self._emit(self.next_emit, self.lattice.t)

    def _step_after_last_emitted(self, node: int, edge: int) -> int:
        """Metadata row of the step from the last emitted sample into the first one to emit: the arriving edge if
        it leaves the last emitted node, else the node's own natural step (the decoder changed its mind; the pose
        jumps but the root path stays continuous)."""
        g = self.graph
        return int(g.edge_meta[edge] if edge >= 0 and g.edge_src[edge] == self._last[2] else g.node_arrival[node])

    def _start_after_last_emitted(self, node: int, edge: int) -> tuple[complex, float] | None:
        """Markov (accelerometer-only) search: the global state of the first sample to emit, continuing from the
        last emitted one (see `_step_after_last_emitted`)."""
        if self._last is None:
            return None  # first sample: the lattice's start state
        ground, heading, _ = self._last
        row = self._step_after_last_emitted(node, edge)
        d = complex(*self.graph.meta_dpos_m[row])
        return ground + d * np.exp(-1j * heading), heading + self.graph.meta_dheading_rad[row]

    def _emit(self, first: int, last: int) -> list[EmittedPose]:
        lat = self.lattice
        best = lat.best_node()
        nodes, edges = lat.backtrace(best, lat.t - first)
        if lat.warp.active:  # replay the warped root from the last emitted sample (or the first input)
            if self._last is None:
                ground, heading = lat.warped_states(edges, first, lat.start_state, None)
            else:
                ground, heading = lat.warped_states(edges, first, self._last[:2],
                                                    self._step_after_last_emitted(int(nodes[0]), int(edges[0])))
        else:
            start = None if lat.track_global else self._start_after_last_emitted(int(nodes[0]), int(edges[0]))
            ground, heading = lat.global_states(best, edges, start)
        k = last - first + 1
        nodes, ground, heading = nodes[:k], ground[:k], heading[:k]
        out_ground, out_heading = self._fuser.decide(ground, heading)
        joints = world_joint_positions(self.graph, nodes, out_ground, out_heading)
        self.next_emit = last + 1
        self._last = (complex(*ground[-1]), float(heading[-1]), int(nodes[-1]))
        lat.drop_before(self.next_emit)
        conf = [confidence(self._history.per_sample_around(first + i), self.confidence_reference) for i in range(k)]
        self._history.drop_before(self.next_emit)
        return [EmittedPose(first + i, int(nodes[i]), joints[i], out_ground[i], float(out_heading[i]), conf[i])
                for i in range(k)]
