"""Placing graph poses in the world: a node's joints live in its source clip's frame; a path carries its own
global ground position and heading, so each pose is turned and moved onto the path."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from engine.mocap import quaternions as quat

from .geometry import rotate_ground

if TYPE_CHECKING:  # annotations only: the graph build (graph.py -> interpolate.py) imports this module
    from .graph import MotionGraph


def world_joint_positions(graph: MotionGraph, nodes: np.ndarray, ground_m: np.ndarray,
                          heading_rad: np.ndarray) -> np.ndarray:
    """(T, J, 3) joint positions (m, world frame) of `nodes` placed at the path's (ground, heading) per sample."""
    nodes = np.asarray(nodes, dtype=np.intp)
    return place_node_points(graph, nodes, graph.node_positions_m[nodes].astype(float), ground_m, heading_rad)


def place_node_points(graph: MotionGraph, nodes: np.ndarray, pts: np.ndarray, ground_m: np.ndarray,
                      heading_rad: np.ndarray) -> np.ndarray:
    """(T, J, 3) points given in each node's clip frame (its pose, possibly re-posed: orientation_pose) placed at
    the path's (ground, heading) per sample, as `world_joint_positions` places the node's own pose."""
    pts = np.array(pts, float, copy=True)
    pts[..., 0] -= graph.node_ground_m[nodes, 0][:, None]
    pts[..., 2] -= graph.node_ground_m[nodes, 1][:, None]
    turn = np.asarray(heading_rad, float) - graph.node_heading_rad[nodes]
    pts[..., [0, 2]] = rotate_ground(pts[..., [0, 2]], turn[:, None])
    pts[..., 0] += np.asarray(ground_m)[:, 0][:, None]
    pts[..., 2] += np.asarray(ground_m)[:, 1][:, None]
    return pts


def root_local(joints_m: np.ndarray, ground_m: np.ndarray, heading_rad: np.ndarray) -> np.ndarray:
    """Joints (T, J, 3) expressed in each frame's root frame (ground origin under the root, facing +Z): the
    frame in which poses are compared for the joint error and averaged for interpolation."""
    out = np.array(joints_m, float, copy=True)
    out[..., 0] -= np.asarray(ground_m)[:, 0, None]
    out[..., 2] -= np.asarray(ground_m)[:, 1, None]
    out[..., [0, 2]] = rotate_ground(out[..., [0, 2]], -np.asarray(heading_rad)[:, None])
    return out


def blended_joint_positions(graph: MotionGraph, blend_nodes: np.ndarray, ground_m: np.ndarray,
                            heading_rad: np.ndarray, node_points: np.ndarray | None = None) -> np.ndarray:
    """(T, J, 3) the mean of the poses of `blend_nodes` (T, k), each placed at the path's (ground, heading) per
    sample: the k poses averaged in the root frame (placement is linear in the root-frame pose). `node_points`
    (T, k, J, 3): the nodes' poses re-posed in their clip frames (orientation_pose), else their own."""
    blend_nodes = np.asarray(blend_nodes, dtype=np.intp)
    t, k = blend_nodes.shape
    flat = blend_nodes.reshape(-1)
    pts = graph.node_positions_m[flat] if node_points is None else np.asarray(node_points).reshape(t * k, -1, 3)
    placed = place_node_points(graph, flat, pts, np.repeat(ground_m, k, axis=0), np.repeat(heading_rad, k))
    return placed.reshape(t, k, -1, 3).mean(axis=1)


def node_global_rotations(graph: MotionGraph, nodes: np.ndarray) -> np.ndarray:
    """(..., J, 4) each joint's rotation in the clip frame (the product of the local rotations from the root down)
    of the poses of `nodes` (...,): what segment posing turns (orientation_pose), so the posed pose stays
    rotations."""
    local = graph.node_rotations[np.asarray(nodes, dtype=np.intp)].astype(float)
    glob = np.empty_like(local)
    glob[..., 0, :] = local[..., 0, :]
    for j, p in enumerate(graph.skeleton.parents[1:], start=1):  # parents come before children
        glob[..., j, :] = quat.multiply(glob[..., p, :], local[..., j, :])
    return glob


def local_from_global(parents: np.ndarray, glob: np.ndarray) -> np.ndarray:
    """(..., J, 4) local joint rotations of global ones (..., J, 4): local_j = global_parent⁻¹ global_j."""
    parents = np.asarray(parents)
    local = np.array(glob, float, copy=True)
    local[..., 1:, :] = quat.multiply(quat.conjugate(glob[..., parents[1:], :]), glob[..., 1:, :])
    return local
