"""Tilt from low-passed accelerations (issue 18 item 3): the accelerometer-only search's gravity features.

Why: in slow motion an accelerometer reads mostly gravity, i.e. each segment's tilt; in C_A that signal is mixed
with the dynamic part sample by sample. A causal low-pass of each sensor's accelerations, normalised, estimates the
sensor's up axis in its own frame. The features are extra columns of the C_A squared distance (as the orientation
term's: viterbi.ViterbiLattice appends 3S rows to its metadata), scaled by sqrt(weight x the database's acc
variance / the features' variance) so that at weight 1 neither part drowns the other.

The database side is low-passed the same way, causally along each source clip (the lag then matches the live
side's): an exponential moving average over the original nodes in frame order of their arrival rows'
accelerations; a slow-down node (frame x.5) takes its clip's value at the frame before; every metadata row takes
the value of the node it arrives at. The live side is one moving average per sensor axis, pushed once per sample in
order (the batch search with forgetting and the fixed-lag decoder step through the same
`viterbi.step_arguments`, so live = offline bit for bit). Off by default (`SearchWeights.gravity` = 0): measured
worse on held-out gestures (docs/engine-evaluation.md, "Accelerations that listen").
"""
from __future__ import annotations

import numpy as np

from .graph import MotionGraph
from .orientation_term import row_nodes, scaled_rows
from .parts import NODE_ORIGINAL

TIME_CONSTANT_S = 0.5  # the low-pass's memory: longer than a gesture's accelerations swing, short enough to
# follow a limb's tilt through a slow gesture


def ema_weight(fps: float, time_constant_s: float) -> float:
    """The moving average's weight of each new sample."""
    return 1.0 / (1.0 + time_constant_s * fps)


def unit(acc_g: np.ndarray) -> np.ndarray:
    """(..., 3) the directions of low-passed accelerations (the sensor's up axis while the segment is still)."""
    return acc_g / np.maximum(np.linalg.norm(acc_g, axis=-1, keepdims=True), 1e-9)


def node_low_passed(graph: MotionGraph, sensor_indices: list[int], alpha: float) -> np.ndarray:
    """(N, S, 3) each node's low-passed accelerations along its source clip (see the module docstring)."""
    acc = np.asarray(graph.meta_acc_g, float)[graph.node_arrival][:, sensor_indices]
    out = np.zeros_like(acc)
    original = graph.node_kind == NODE_ORIGINAL
    frame = np.floor(graph.node_frame).astype(np.int64)
    for clip in np.unique(graph.node_clip):
        in_clip = graph.node_clip == clip
        nodes = np.flatnonzero(in_clip & original)
        nodes = nodes[np.argsort(frame[nodes], kind="stable")]
        mean = acc[nodes[0]].copy()
        for n in nodes:
            mean += alpha * (acc[n] - mean)
            out[n] = mean
        others = np.flatnonzero(in_clip & ~original)  # slow-down nodes: the value at the frame before
        at = np.clip(np.searchsorted(frame[nodes], frame[others], side="right") - 1, 0, len(nodes) - 1)
        out[others] = out[nodes[at]]
    return out


class GravityTerm:
    """The database side (`meta_rows_t`: scaled feature rows (3S, M) float32 to append to the lattice's acc
    metadata) and the live encoder's state for one sensor selection."""

    def __init__(self, graph: MotionGraph, sensor_indices: list[int], weight: float,
                 time_constant_s: float = TIME_CONSTANT_S) -> None:
        self.alpha = ema_weight(graph.config.fps, time_constant_s)
        nodes = row_nodes(graph)
        used = nodes >= 0
        f = unit(node_low_passed(graph, sensor_indices, self.alpha))[np.where(used, nodes, 0)]  # (M, S, 3)
        self.scale, self.meta_rows_t = scaled_rows(graph, sensor_indices, f, used, weight)
        self._mean: np.ndarray | None = None  # the live low-pass, None before the first sample

    def push(self, acc_g: np.ndarray | None) -> np.ndarray | None:
        """This sample's scaled features (S, 3) (None when it has no accelerations: the low-pass holds)."""
        if acc_g is None:
            return None
        a = np.asarray(acc_g, float).reshape(-1, 3)
        self._mean = a.copy() if self._mean is None else self._mean + self.alpha * (a - self._mean)
        return unit(self._mean) * self.scale
