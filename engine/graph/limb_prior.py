"""Where an unworn upper arm or thigh points, from the worn forearm or shin below it (issue 18): the database's
answer, looked up limb by limb.

Why: posing turns each worn segment onto its sensor, but the upper arm above a worn forearm carries no sensor, so
the elbow stays where the *played* pose has it (or, with the hinge share, moves with the forearm's turn as a
whole limb). On gestures the database lacks the played elbow is the largest remaining error (measured: right
elbow 17 cm against 5-8 cm for the worn segments' joints). The forearm's orientation relative to the chest does
say a lot about the upper arm -- people hold their arms in a few ways for a given forearm attitude -- and the
database has many more *arm* poses than whole-body poses near any one frame. So per worn limb segment the k
database poses (every node of the graph) whose segment orientation relative to its worn anchor (chest above a
forearm, pelvis above a shin) is nearest the measured one vote for the upper limb's direction in the anchor's
frame: the mean of their unit directions. The whole-pose search cannot do this: it must match all six sensors
with one database frame at once.

With calibrated orientations (yaw relative to the anchor known) the key is the segment's rotation relative to
its anchor; distances are chordal (the 3x3 rotation matrices' Frobenius distance, monotone in the relative
angle), so a kd-tree over the 9 matrix entries finds the nearest rotations exactly. Without a calibration, or
with tilts from accelerations, the relative yaw is unknown and the key is the two sensors' up axes alone."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from engine.mocap import quaternions as quat

from .orientation_term import UP


class LimbPrior:
    """The per-limb lookup for a set of hinge limbs: worn segment `segments[h]` (a sensor index) below its worn
    `anchors[h]` (a sensor index), the unworn upper limb from joint `pivots[h]` to joint `ends[h]` (shoulder ->
    elbow, hip -> knee)."""

    def __init__(self, node_orientations: np.ndarray, node_positions_m: np.ndarray, segments: np.ndarray,
                 anchors: np.ndarray, pivots: np.ndarray, ends: np.ndarray, k: int) -> None:
        """`node_orientations` (N, S, 4) every node's sensor orientations and `node_positions_m` (N, J, 3) its
        joints, in the same (clip) frame."""
        self.segments, self.anchors = np.asarray(segments, int), np.asarray(anchors, int)
        self.k = int(min(k, len(node_orientations)))
        anchor_q = quat.conjugate(node_orientations[:, self.anchors])  # (N, H, 4) world -> anchor
        relative = quat.multiply(anchor_q, node_orientations[:, self.segments])
        limb = node_positions_m[:, ends] - node_positions_m[:, pivots]
        limb_local = quat.rotate(anchor_q, limb / np.linalg.norm(limb, axis=-1, keepdims=True))
        self._trees = [cKDTree(_matrix_features(relative[:, h])) for h in range(len(self.segments))]
        tilts = _tilt_features(node_orientations[:, self.anchors], node_orientations[:, self.segments])
        self._tilt_trees = [cKDTree(tilts[:, h]) for h in range(len(self.segments))]
        self._directions = [limb_local[:, h] for h in range(len(self.segments))]  # (N, 3) unit, anchor frame

    def directions(self, anchor_q: np.ndarray, segment_q: np.ndarray, limbs: np.ndarray, tilt_only: bool
                   ) -> np.ndarray:
        """(..., L, 3) unit upper-limb directions, in each limb's anchor frame, for the anchors' and worn
        segments' world orientations `anchor_q`, `segment_q` (..., L, 4) (finite) of the limbs `limbs` (L,).
        `tilt_only`: their yaws are not known (no calibration, or tilts from accelerations), so the lookup reads
        each one's up axis alone (segment and anchor: 6 numbers, no relative yaw)."""
        if tilt_only:
            feats, trees = _tilt_features(anchor_q, segment_q), self._tilt_trees
        else:
            feats = _matrix_features(quat.multiply(quat.conjugate(anchor_q), segment_q))
            trees = self._trees
        out = np.empty(feats.shape[:-1] + (3,))
        for column, h in enumerate(limbs):
            f = feats[..., column, :].reshape(-1, feats.shape[-1])
            _, idx = trees[h].query(f, k=self.k)
            mean = self._directions[h][idx.reshape(len(f), -1)].mean(axis=1)
            out[..., column, :] = (mean / np.maximum(np.linalg.norm(mean, axis=-1, keepdims=True), 1e-12)
                                   ).reshape(feats.shape[:-2] + (3,))
        return out


def _matrix_features(q: np.ndarray) -> np.ndarray:
    """(..., 9) rotation-matrix entries of quaternions (..., 4): Euclidean distance = chordal rotation distance."""
    return quat.to_matrix(q).reshape(q.shape[:-1] + (9,))


def _tilt_features(anchor_q: np.ndarray, segment_q: np.ndarray) -> np.ndarray:
    """(..., 6) the yaw-free key: the segment's then the anchor's up axis in its own frame ((..., 4) each)."""
    return np.concatenate([quat.rotate(quat.conjugate(segment_q), UP),
                           quat.rotate(quat.conjugate(anchor_q), UP)], axis=-1)


def rotation_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(..., 4) the shortest rotation taking unit vectors `u` onto `v` (..., 3) (antiparallel: a half turn about
    any axis perpendicular to u)."""
    cross = np.cross(u, v)
    dot = np.sum(u * v, axis=-1, keepdims=True)
    q = np.concatenate([1.0 + dot, cross], axis=-1)
    flip = (1.0 + dot[..., 0]) < 1e-9
    if np.any(flip):
        perp = np.cross(u[flip], [1.0, 0.0, 0.0])
        perp = np.where(np.linalg.norm(perp, axis=-1, keepdims=True) < 1e-6, np.cross(u[flip], [0.0, 1.0, 0.0]), perp)
        q[flip] = np.concatenate([np.zeros((len(perp), 1)), perp], axis=-1)
    return quat.normalize(q)
