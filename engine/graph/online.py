"""Online synthesis: a fixed-lag Viterbi decoder (sensor streams reach the graph rate through `engine.stream`).

At sample t the decoder advances the lattice (O(E)), then decides sample t - L by back-tracing L steps from the
currently best node: the latency is L samples and the memory L lattice columns (older ones are dropped).
With L >= the sequence length nothing is decided before `flush()`, which back-traces the whole lattice exactly
as the batch search does -- the two are the same computation.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from engine.mocap.orientation_calibration import OrientationCalibration

from .graph import MotionGraph
from .orientation_pose import SegmentPosing
from .decided import decided_poses
from .viterbi import (DEFAULT_KERNEL, PRUNE_EVERY, Constraint, Observations, SearchResult, SearchWeights,
                      ViterbiLattice, step_arguments)
from .confidence import CostHistory, CostWindow, confidence, reference_cost_per_sample
from .root_fusion import RootFuser, RootFusion
from .warp import RootWarp


@dataclass(frozen=True)
class EmittedPose:
    """The decided pose of sample `t`: graph node, joint positions (J, 3) m in the world frame (the forward
    kinematics of `root_m` and `local_rotations` when the graph stores rotations), the output root's
    ground position (x, z) m and heading rad (the camera's smoothed track with root fusion, else the path's), and `confidence` in [0, 1] (confidence.py: 1 = the search costs
    what the database's own clips cost; towards 0 = the engine is lost)."""

    t: int
    node: int
    joint_positions_m: np.ndarray
    ground_m: np.ndarray
    heading_rad: float
    confidence: float = 1.0
    edge: int = -1  # graph edge from the previous emitted node into `node`; -1: first sample, or the decoder
    # changed its mind (the previous emitted node is not this edge's source)
    blend_nodes: np.ndarray | None = None  # (k,) nodes whose mean pose `joint_positions_m` is (blend_paths > 1)
    root_m: np.ndarray | None = None  # (3,) m and (J, 4) local rotations (w, x, y, z): the decided pose, whose
    local_rotations: np.ndarray | None = None  # forward kinematics `joint_positions_m` is (decided.py)


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
    supplying the root-relative pose (and the root only where the camera is absent); off = the path's own root.

    Samples pushed with orientations get their worn segments posed onto them (orientation_pose.SegmentPosing,
    `weights.segment_pose`; yaw relative to the pelvis too with an `orientation_calibration` from the N-pose
    capture, else tilt only)."""

    def __init__(self, graph: MotionGraph, lag_s: float, weights: SearchWeights = SearchWeights(),
                 sensor_indices: tuple[int, ...] | None = None, prune_every: int = PRUNE_EVERY,
                 kernel: str = DEFAULT_KERNEL, warp: RootWarp = RootWarp.off(),
                 confidence_reference: float | None = None, confidence_window_s: float = 2.0,
                 reanchor_ratio: float = 4.0, reanchor_after_s: float = 3.0,
                 fusion: RootFusion = RootFusion.off(),
                 orientation_calibration: OrientationCalibration | None = None) -> None:
        if lag_s < 0:
            raise ValueError("lag must be non-negative")
        self.graph = graph
        self.lag = int(round(lag_s * graph.config.fps))  # samples between a push and the pose it emits
        # a forgetting search decides sooner (SearchWeights.decision_frames) and holds the decided samples until
        # the lag has passed, so the fused root (root_fusion.py) still smooths the camera over the whole lag
        self.decision_lag = min(self.lag, weights.decision_frames) if weights.forgets else self.lag
        self.lattice = ViterbiLattice(graph, weights, sensor_indices, prune_every, kernel, warp,
                                      orientation_calibration)
        self.next_emit = 0  # first sample not yet emitted
        self.next_decide = 0  # first sample not yet decided
        self._decided: list[tuple] = []  # (node, edge, ground, heading, blend nodes) of samples next_emit.. decided
        self._last: tuple[complex, float, int] | None = None  # the path's (ground, heading, node) at the last decided
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
        self._posing = SegmentPosing.for_search(graph, tuple(range(graph.n_sensors)) if sensor_indices is None
                                                else tuple(sensor_indices), weights, orientation_calibration)
        self._pose_inputs: list[tuple[np.ndarray, np.ndarray]] = []  # SegmentPosing.sample of samples next_emit..

    def push(self, acc_g: np.ndarray | None, pos_m: np.ndarray | None = None, heading_rad: float | None = None,
             penalty: np.ndarray | None = None, rows: np.ndarray | None = None, *,
             quat_wxyz: np.ndarray | None = None, gyro_rps: np.ndarray | None = None) -> list[EmittedPose]:
        """Consume sample t (acc (S, 3) g, optional ground position (2,) m and heading rad; `penalty` = optional
        per-node broken-constraint count for this sample; `rows` = this sample's `acc_rows_batch` row if the
        caller batched them; `quat_wxyz` (S, 4) the sensors' device-earth orientations, used when the weights
        turn the orientation term on; `gyro_rps` is accepted and not used); returns the pose of sample t - L once
        t >= L."""
        lat = self.lattice
        lat.step(acc_g, pos_m, heading_rad, penalty, rows, quat_wxyz)
        self._fuser.push(pos_m, heading_rad)
        if self._posing is not None:
            self._pose_inputs.append(self._posing.sample(acc_g, quat_wxyz))
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
        if t - self.decision_lag >= self.next_decide:
            self._decide(t - self.decision_lag, t - self.decision_lag)
        if t - self.lag < self.next_emit:
            return []
        return self._emit(t - self.lag)

    def flush(self) -> list[EmittedPose]:
        """End of input: decide every sample not yet decided, along the final best path, and emit everything."""
        if self.lattice.t < self.next_emit:
            return []
        if self.lattice.t >= self.next_decide:
            self.lattice.prune()
            self._decide(self.next_decide, self.lattice.t)
        return self._emit(self.lattice.t)

    def _step_after_last_decided(self, node: int, edge: int) -> int:
        """Metadata row of the step from the last decided sample into the first one to decide: the arriving edge if
        it leaves the last decided node, else the node's own natural step (the decoder changed its mind; the pose
        jumps but the root path stays continuous)."""
        g = self.graph
        return int(g.edge_meta[edge] if edge >= 0 and g.edge_src[edge] == self._last[2] else g.node_arrival[node])

    def _start_after_last_decided(self, node: int, edge: int) -> tuple[complex, float] | None:
        """Markov (accelerometer-only) search: the global state of the first sample to decide, continuing from the
        last decided one (see `_step_after_last_decided`)."""
        if self._last is None:
            return None  # first sample: the lattice's start state
        ground, heading, _ = self._last
        row = self._step_after_last_decided(node, edge)
        d = complex(*self.graph.meta_dpos_m[row])
        return ground + d * np.exp(-1j * heading), heading + self.graph.meta_dheading_rad[row]

    def _decide(self, first: int, last: int) -> None:
        """Samples first..last along the best path now: nodes, arriving edges (-1 where the decoder changed its
        mind since the last decided sample), the path's root (the warped replay from the last decided sample) and,
        with `blend_paths` > 1, the nodes of the best paths at each sample."""
        lat = self.lattice
        best = lat.best_node()
        nodes, edges = lat.backtrace(best, lat.t - first)
        if lat.warp.active:  # replay the warped root from the last decided sample (or the first input)
            if self._last is None:
                ground, heading = lat.warped_states(edges, first, lat.start_state, None)
            else:
                ground, heading = lat.warped_states(edges, first, self._last[:2],
                                                    self._step_after_last_decided(int(nodes[0]), int(edges[0])))
        else:
            start = None if lat.track_global else self._start_after_last_decided(int(nodes[0]), int(edges[0]))
            ground, heading = lat.global_states(best, edges, start)
        k = last - first + 1
        nodes, ground, heading = nodes[:k], ground[:k], heading[:k]
        blend = [None] * k
        if lat.weights.blend_paths > 1:  # row i: the k best paths at sample first + i
            blend = list(lat.ancestors(lat.weights.blend_paths, lat.t - first)[::-1][:k])
        edges = edges[:k].copy()
        if self._last is not None and edges[0] >= 0 and self.graph.edge_src[edges[0]] != self._last[2]:
            edges[0] = -1  # the decoder changed its mind since the last decided sample
        self.next_decide = last + 1
        lat.learn_orientation(first, nodes)
        self._last = (complex(*ground[-1]), float(heading[-1]), int(nodes[-1]))
        lat.drop_before(self.next_decide)
        self._decided += [(int(nodes[i]), int(edges[i]), ground[i], float(heading[i]), blend[i]) for i in range(k)]

    def _emit(self, last: int) -> list[EmittedPose]:
        """The decided samples next_emit..last as poses: the output root (fused from the camera over the lag, or
        the path's), the joints (the path's pose, or the blend of the best paths'), the confidence."""
        first = self.next_emit
        k = last - first + 1
        out, self._decided = self._decided[:k], self._decided[k:]
        nodes = np.array([d[0] for d in out], dtype=np.int64)
        ground = np.array([d[2] for d in out], dtype=float).reshape(-1, 2)
        heading = np.array([d[3] for d in out], dtype=float)
        out_ground, out_heading = self._fuser.decide(ground, heading)
        blend = np.stack([d[4] for d in out]) if out[0][4] is not None else nodes[:, None]
        inputs, self._pose_inputs = self._pose_inputs[:k], self._pose_inputs[k:]
        if self._posing is not None:
            decided = self._posing.decide(blend, out_ground, out_heading, np.stack([i[0] for i in inputs]),
                                          np.stack([i[1] for i in inputs]))
        else:  # a single path is a blend of one (the mean of one pose is that pose)
            decided = decided_poses(self.graph, blend, out_ground, out_heading)
        self.next_emit = last + 1
        conf = [confidence(self._history.per_sample_around(first + i), self.confidence_reference) for i in range(k)]
        self._history.drop_before(self.next_emit)
        roots, rots = decided.root_m, decided.local_rotations
        return [EmittedPose(first + i, int(nodes[i]), decided.joint_positions_m[i], out_ground[i],
                            float(out_heading[i]), conf[i], out[i][1], out[i][4],
                            None if roots is None else roots[i], None if rots is None else rots[i])
                for i in range(k)]


def decide_with_forgetting(graph: MotionGraph, weights: SearchWeights, obs: Observations,
                           constraints: list[Constraint] | None = None, prune_every: int = PRUNE_EVERY,
                           kernel: str = DEFAULT_KERNEL, warp: RootWarp = RootWarp.off()) -> SearchResult:
    """The batch search of a forgetting search (`ViterbiSearch.run` with `weights.forgets`): the fixed-lag decoder
    over the whole take with lag `weights.decision_frames`, so offline and live decide every sample the same way
    (bit for bit: both step through `viterbi.step_arguments`)."""
    # the batch caller keeps only the decisions and poses them once over the take (orientation_pose.
    # decided_joint_positions): no posing of the emitted joints here, which would be thrown away
    syn = FixedLagSynthesizer(graph, weights.decision_frames / graph.config.fps, replace(weights, segment_pose=0.0),
                              obs.sensor_indices,
                              prune_every, kernel, warp, confidence_reference=float("nan"), reanchor_ratio=0.0,
                              orientation_calibration=obs.orientation_calibration)
    lat = syn.lattice
    poses: list[EmittedPose] = []
    for step in step_arguments(lat, obs, constraints):
        poses += syn.push(*step[:5], quat_wxyz=step[5])
    best = lat.best_node()
    cost, broken = lat.cost_of(best), lat.broken_of(best)
    poses += syn.flush()
    return SearchResult(nodes=np.array([p.node for p in poses], dtype=np.int64),
                        edges=np.array([p.edge for p in poses], dtype=np.int64),
                        ground_m=np.array([p.ground_m for p in poses], dtype=float).reshape(-1, 2),
                        heading_rad=np.array([p.heading_rad for p in poses], dtype=float), cost=cost,
                        broken_constraints=broken, compression_ratio=lat.compression_ratio(),
                        lattice_entries=lat.lattice_entries(),
                        blend_nodes=None if weights.blend_paths == 1 else np.stack([p.blend_nodes for p in poses]))
