"""Per-sensor weights of C_A from how much each sensor tells about pose (issue 18 item 3).

Why: C_A sums every sensor's squared distance alike, yet a sensor whose accelerations differ little between
different poses and much between moments of the same pose (a shin in a standing gesture) only adds noise to the
match. Over the database: for every `STRIDE`-th original node, its nearest pose among the nodes of the other clips
(root-relative: the non-root joints' local rotations); per sensor, the within-pose spread = the mean squared
acceleration difference over those pairs, the between-pose spread = twice the sensor's total variance. The weight
is (between / within) ** `power`, normalised to mean 1 over the selected sensors (so C_A's scale is kept).
On in the live preset at power -4 (`SearchWeights.camera_following`; 0 elsewhere): docs/engine-evaluation.md.
"""
from __future__ import annotations

import numpy as np

from .graph import MotionGraph
from .parts import NODE_ORIGINAL

STRIDE = 16  # every 16th original node is paired (~2000 pairs on Bandai-1: seconds, once per search)


def pose_features(rotations: np.ndarray) -> np.ndarray:
    """(N, 4 (J - 1)) root-relative pose: the non-root joints' local quaternions, sign-fixed (w >= 0)."""
    q = np.asarray(rotations[:, 1:], np.float32)
    q = np.where(q[..., :1] < 0, -q, q)
    return q.reshape(len(q), -1)


def fisher_ratios(graph: MotionGraph, sensor_indices: list[int]) -> np.ndarray:
    """(S,) between-pose / within-pose spread of each sensor's accelerations (module docstring)."""
    if graph.node_rotations is None:
        raise ValueError("this graph stores no joint rotations: rebuild it to weight sensors by pose")
    original = np.flatnonzero(graph.node_kind == NODE_ORIGINAL)
    pose = pose_features(graph.node_rotations[original])
    acc = np.asarray(graph.meta_acc_g, float)[graph.node_arrival[original]][:, sensor_indices]  # (n, S, 3)
    clip = graph.node_clip[original]
    within = np.zeros(len(sensor_indices))
    queries = np.arange(0, len(original), STRIDE)
    sq = np.einsum("ij,ij->i", pose, pose)
    for chunk in np.array_split(queries, max(1, len(queries) // 256)):
        d = sq[chunk, None] - 2.0 * pose[chunk] @ pose.T + sq[None]
        d[clip[chunk, None] == clip[None]] = np.inf  # the nearest pose of another clip
        nn = np.argmin(d, axis=1)
        within += ((acc[chunk] - acc[nn]) ** 2).sum(axis=(0, 2))
    within /= len(queries)
    between = 2.0 * acc.var(axis=0).sum(axis=1)
    return between / np.maximum(within, 1e-12)


def sensor_weights(graph: MotionGraph, sensor_indices: list[int], power: float) -> np.ndarray:
    """(S,) weights (between / within) ** power, mean 1. The ratios are computed once per graph object and sensor
    selection (seconds on Bandai-1; every search of an evaluation builds a lattice)."""
    cache = graph.__dict__.setdefault("_fisher_ratios", {})
    key = tuple(sensor_indices)
    if key not in cache:
        cache[key] = fisher_ratios(graph, sensor_indices)
    w = cache[key] ** power
    return w / w.mean()
