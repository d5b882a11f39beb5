"""The motion graph's decided poses (issue 29): the blend of the best paths' poses, each re-posed onto the
sensors (orientation_pose), placed on the output root path -- as root positions and local joint rotations, with
the joint positions their forward kinematics.

Why rotations: the console, the poses file, the BVH file and the BVH / VMC streams all read this one pose
(engine.stream.decided). The blend averages rotations (`postprocess.place_blend`, the chordal mean per joint)
and the posing turns joint rotations (`SegmentPoser.pose`), so a BVH written from the rotations gives back the
joints the console drew."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.mocap import pose_joint_positions

from .graph import MotionGraph
from .postprocess import place_blend
from .poses import blended_joint_positions, local_from_global


@dataclass(frozen=True)
class DecidedPoses:
    """T decided poses: ``joint_positions_m`` (T, J, 3) world m, and the pose they come from, ``root_m`` (T, 3) m
    and ``local_rotations`` (T, J, 4) (w, x, y, z), None for a graph without joint rotations or skeleton
    (plain-array test graphs: positions are all there is)."""

    joint_positions_m: np.ndarray
    root_m: np.ndarray | None = None
    local_rotations: np.ndarray | None = None


def decided_poses(graph: MotionGraph, blend_nodes: np.ndarray, ground_m: np.ndarray, heading_rad: np.ndarray,
                  global_rotations: np.ndarray | None = None) -> DecidedPoses:
    """The mean pose of `blend_nodes` (T, k) placed at (ground (T, 2) m, heading (T,) rad); `global_rotations`
    (T, k, J, 4): the columns re-posed in their clip frames (`SegmentPoser.pose`), else the nodes' own poses."""
    blend_nodes = np.asarray(blend_nodes, dtype=np.intp)
    if graph.node_rotations is None or graph.node_root_m is None or graph.skeleton is None:
        return DecidedPoses(blended_joint_positions(graph, blend_nodes, ground_m, heading_rad))
    local = None if global_rotations is None else local_from_global(graph.skeleton.parents, global_rotations)
    root, rots = place_blend(graph, blend_nodes, np.asarray(ground_m, float).reshape(-1, 2),
                             np.asarray(heading_rad, float), local)
    return DecidedPoses(pose_joint_positions(graph.skeleton, root, rots), root, rots)
