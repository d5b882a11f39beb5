"""Baselines every engine must beat, computed from the same database (the held-out-free graph) and the same
simulated inputs.

* mean pose: the database's mean root-frame pose, placed at the camera's root position and heading (or, with
  no camera, standing at the first fix): no motion at all.
* nearest neighbour: the take cut into windows; each window's sensor features (stacked accelerations of the
  worn sensors over the window) matched to the closest window of any database clip, whose poses are played;
  placed at the camera, or without a camera dead-reckoned from the database clips' own root steps.
"""
from __future__ import annotations

import numpy as np

from engine.graph.geometry import rotate_ground
from engine.graph.graph import MotionGraph
from engine.graph.parts import NODE_ORIGINAL
from engine.graph.poses import root_local


def place_local_poses(local_m: np.ndarray, ground_m: np.ndarray, heading_rad: np.ndarray) -> np.ndarray:
    """Root-frame poses (T, J, 3) or one pose (J, 3) -> world (T, J, 3) at the given ground position/heading."""
    ground_m, heading_rad = np.asarray(ground_m, float), np.asarray(heading_rad, float)
    out = np.array(np.broadcast_to(local_m, (len(heading_rad),) + np.shape(local_m)[-2:]), float)
    out[..., [0, 2]] = rotate_ground(out[..., [0, 2]], heading_rad[:, None]) + ground_m[:, None, :]
    return out


def _original(graph: MotionGraph) -> np.ndarray:
    return np.flatnonzero(graph.node_kind == NODE_ORIGINAL)


def node_local_poses(graph: MotionGraph, nodes: np.ndarray) -> np.ndarray:
    """(K, J, 3) the nodes' poses in their own root frames."""
    return root_local(graph.node_positions_m[nodes].astype(float), graph.node_ground_m[nodes],
                      graph.node_heading_rad[nodes])


def mean_local_pose(graph: MotionGraph) -> np.ndarray:
    """(J, 3) mean root-frame pose over the graph's database frames (slow-down / interpolated nodes excluded)."""
    return node_local_poses(graph, _original(graph)).mean(axis=0)


def mean_pose(graph: MotionGraph, ground_m: np.ndarray, heading_rad: np.ndarray) -> np.ndarray:
    """(T, J, 3) world joints of the mean pose placed at every frame's (ground, heading)."""
    return place_local_poses(mean_local_pose(graph), ground_m, heading_rad)


def dead_reckoned(graph: MotionGraph, nodes: np.ndarray, ground0_m: np.ndarray, heading0_rad: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Root ground/heading per sample from the nodes' own arrival steps (eq. 5), starting at the given state."""
    rows = graph.node_arrival[nodes]
    dh = graph.meta_dheading_rad[rows].copy()
    dh[0] = 0.0
    heading = heading0_rad + np.cumsum(dh)
    steps = rotate_ground(graph.meta_dpos_m[rows], np.r_[heading0_rad, heading[:-1]])
    steps[0] = 0.0
    return np.asarray(ground0_m, float) + np.cumsum(steps, axis=0), heading


class NearestNeighbour:
    """Per-window nearest neighbour on sensor features over every `window`-frame run of a database clip."""

    def __init__(self, graph: MotionGraph, sensor_indices: tuple[int, ...], window: int = 15) -> None:
        orig = _original(graph)
        clip, frame = graph.node_clip[orig], graph.node_frame[orig]
        # window starts k with nodes orig[k .. k+window-1] consecutive frames of one clip
        k = np.arange(len(orig) - window + 1)
        ok = (clip[k + window - 1] == clip[k]) & (frame[k + window - 1] == frame[k] + window - 1)
        self.graph, self.window, self.sensors, self.orig = graph, window, tuple(sensor_indices), orig
        self.starts = k[ok]  # positions in `orig`
        if len(self.starts) == 0:
            raise ValueError(f"no database clip is {window} frames long")
        acc = graph.meta_acc_g[graph.node_arrival[orig]][:, list(self.sensors)].reshape(len(orig), -1)
        self.features = np.stack([acc[self.starts + i] for i in range(window)], axis=1).reshape(len(self.starts), -1)
        self.sq_norms = np.einsum("ij,ij->i", self.features, self.features)

    def match(self, acc_g: np.ndarray) -> np.ndarray:
        """(T,) database node per take frame, from acc (T, S', 3) of this matcher's sensors."""
        n, w = len(acc_g), self.window
        if n < w:
            raise ValueError(f"the take ({n} frames) is shorter than one window ({w})")
        begins = np.arange(0, n, w)
        query_at = np.minimum(begins, n - w)  # the last, partial window matches the take's last full window
        q = np.stack([acc_g[query_at + i] for i in range(w)], axis=1).reshape(len(begins), -1).astype(np.float32)
        d = self.sq_norms[None, :] - 2.0 * q @ self.features.T
        best = self.starts[np.argmin(d, axis=1)]
        t = np.arange(n)
        win = np.minimum(t // w, len(begins) - 1)
        return self.orig[best[win] + (t - query_at[win])]

    def predict(self, acc_g: np.ndarray, ground_m: np.ndarray | None, heading_rad: np.ndarray | None,
                start_ground_m: np.ndarray, start_heading_rad: float) -> tuple[np.ndarray, np.ndarray]:
        """(world joints (T, J, 3), matched nodes (T,)): at the camera if given, else dead-reckoned."""
        nodes = self.match(acc_g)
        if ground_m is None:
            ground_m, heading_rad = dead_reckoned(self.graph, nodes, start_ground_m, start_heading_rad)
        return place_local_poses(node_local_poses(self.graph, nodes), ground_m, heading_rad), nodes


def database_oracle(graph: MotionGraph, true_joints_m: np.ndarray, skeleton, ground_m: np.ndarray,
                    heading_rad: np.ndarray, chunk: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """(world joints (T, J, 3), nodes (T,)): per frame the database pose nearest the truth (squared distance over
    the scored joints, both in their root frames as metrics.frame_errors compares them), placed at the camera.
    Not an engine (it reads the truth): the floor of the root-relative error any database-playing method can
    reach, so a table can say which fraction of the possible gain an engine gets (issue 18)."""
    from engine.mocap import error_joint_indices

    from .metrics import hips_heading

    joints = error_joint_indices(skeleton)
    orig = _original(graph)
    db_pos = graph.node_positions_m[orig].astype(float)
    db = root_local(db_pos[:, joints], db_pos[:, 0, [0, 2]], hips_heading(db_pos, skeleton))
    db = db.reshape(len(orig), -1).astype(np.float32)
    db_sq = np.einsum("ij,ij->i", db, db)
    truth = root_local(true_joints_m[:, joints], true_joints_m[:, 0, [0, 2]], hips_heading(true_joints_m, skeleton))
    truth = truth.reshape(len(truth), -1).astype(np.float32)
    nodes = np.concatenate([orig[np.argmin(db_sq[None] - 2.0 * truth[i:i + chunk] @ db.T, axis=1)]
                            for i in range(0, len(truth), chunk)])
    return place_local_poses(node_local_poses(graph, nodes), ground_m, heading_rad), nodes
