"""Graph poses as rotations: place a path's poses (or the blend of the best paths', re-posed or not) on the output
root path, and pin feet in contact with two-bone IK.

`place_path` / `place_blend` give the decided pose's root and local rotations (engine.graph.decided): the blend
averages each joint's rotation (chordal mean). Seed 000's Bernstein transition blending and the post-hoc foot
IK no longer shape the written BVH: they needed poses not yet decided, so the file differed from what the
console showed (issue 29); the 8-path blend smooths transitions in the decided pose itself. `fix_foot_skate`
stays for the HMM's evaluation, which cleans its own whole-take output.

Foot skate: on every run of frames where a foot is in contact, the ankle is pinned to where it was on the run's
first frame, with an analytic two-bone IK (knee angle by the law of cosines, then a hip rotation that swings the
leg onto the target).
"""
from __future__ import annotations

import numpy as np

from engine.mocap import Motion, forward_kinematics, joint_roles
from engine.mocap import quaternions as quat

from .graph import MotionGraph

UP = np.array([0.0, 1.0, 0.0])



def place_path(graph: MotionGraph, nodes: np.ndarray, ground_m: np.ndarray,
               heading_rad: np.ndarray, local_rotations: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(root positions (T, 3) m, local rotations (T, J, 4)) of the path's poses in the world frame;
    `local_rotations` (T, J, 4): the nodes' poses re-posed in their clip frames (orientation_pose), else their
    own (posing turns joints about joints, never the root joint's position)."""
    if graph.node_rotations is None or graph.node_root_m is None:
        raise ValueError("this graph stores no joint rotations (built from plain arrays): cannot make a Motion")
    nodes = np.asarray(nodes, dtype=np.intp)
    yaw = np.asarray(heading_rad) - graph.node_heading_rad[nodes]
    root = graph.node_root_m[nodes].astype(float).copy()
    rel = root[:, [0, 2]] - graph.node_ground_m[nodes]
    c, s = np.cos(yaw), np.sin(yaw)
    root[:, 0] = ground_m[:, 0] + rel[:, 0] * c + rel[:, 1] * s
    root[:, 2] = ground_m[:, 1] - rel[:, 0] * s + rel[:, 1] * c
    rots = np.array(graph.node_rotations[nodes] if local_rotations is None else local_rotations, float, copy=True)
    rots[:, 0] = quat.multiply(quat.from_rotvec(yaw[:, None] * UP), rots[:, 0])
    return root, rots


def place_blend(graph: MotionGraph, blend_nodes: np.ndarray, ground_m: np.ndarray,
                heading_rad: np.ndarray, local_rotations: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """`place_path` of the mean pose of `blend_nodes` (T, k) (SearchWeights.blend_paths): each column placed on
    the path, root positions averaged, every joint's rotations averaged as quaternions (each turned into the
    first column's hemisphere, summed, normalised -- the chordal mean, close to the rotation mean for the
    nearby poses a blend averages). `local_rotations` (T, k, J, 4): the columns re-posed (`place_path`)."""
    blend_nodes = np.asarray(blend_nodes, dtype=np.intp)
    placed = [place_path(graph, blend_nodes[:, i], ground_m, heading_rad,
                         None if local_rotations is None else local_rotations[:, i])
              for i in range(blend_nodes.shape[1])]
    root = np.mean([r for r, _ in placed], axis=0)
    first = placed[0][1]
    total = np.zeros_like(first)
    for _, q in placed:
        total += np.where(np.sum(q * first, axis=-1, keepdims=True) < 0, -q, q)
    return root, quat.normalize(total)


def _contact_runs(flags: np.ndarray) -> list[tuple[int, int]]:
    padded = np.r_[False, flags, False].astype(int)
    edges = np.flatnonzero(np.diff(padded))
    return list(zip(edges[::2], edges[1::2]))


def _swing(frm: np.ndarray, to: np.ndarray) -> np.ndarray:
    """Shortest-arc quaternions (K, 4) rotating directions `frm` onto `to` (K, 3)."""
    a = frm / np.linalg.norm(frm, axis=1, keepdims=True)
    b = to / np.linalg.norm(to, axis=1, keepdims=True)
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=1, keepdims=True)
    angle = np.arctan2(s[:, 0], np.sum(a * b, axis=1))
    return quat.from_rotvec(np.where(s > 1e-12, axis / np.where(s > 1e-12, s, 1.0), 0.0) * angle[:, None])


def _local_update(rots: np.ndarray, glob: np.ndarray, frames: np.ndarray, joint: int, world_q: np.ndarray) -> None:
    """Apply a world-space rotation to a joint's segment by changing its local rotation:
    local' = local * (G^-1 R G), with G the joint's global rotation."""
    g = quat.from_matrix(glob[frames, joint])
    delta = quat.multiply(quat.multiply(quat.conjugate(g), world_q), g)
    rots[frames, joint] = quat.multiply(rots[frames, joint], delta)


def _pinned_targets(ankle_m: np.ndarray, runs: list[tuple[int, int]], ease_frames: int) -> np.ndarray:
    """Per contact frame, the ankle target: the run's first position, eased back to the free position over
    the run's last `ease_frames` frames so the foot does not pop when the run ends."""
    out = []
    for a, b in runs:
        k = np.arange(a, b)
        w = np.minimum(1.0, (b - k) / max(ease_frames, 1))[:, None]
        out.append(w * ankle_m[a] + (1.0 - w) * ankle_m[k])
    return np.concatenate(out)


def fix_foot_skate(motion: Motion, contacts: np.ndarray, ease_frames: int = 3) -> Motion:
    """Pin each foot's ankle during its contact runs with two-bone IK (hip, knee); returns a new Motion.
    Where the pinned ankle is out of the leg's reach (heel-off at the end of a long stance) the leg is
    stretched towards it."""
    roles = joint_roles(motion.skeleton)
    rots = motion.rotations.copy()
    for col, side in enumerate(("left", "right")):
        hip, knee, ankle = roles[f"{side}_hip"], roles[f"{side}_knee"], roles[f"{side}_ankle"]
        runs = _contact_runs(contacts[:, col])
        if not runs:
            continue
        pos, glob = forward_kinematics(Motion(motion.skeleton, motion.fps, motion.root_positions_m, rots))
        frames = np.concatenate([np.arange(a, b) for a, b in runs])
        target = _pinned_targets(pos[:, ankle], runs, ease_frames)
        a, b, c = pos[frames, hip], pos[frames, knee], pos[frames, ankle]
        l1 = np.linalg.norm(b - a, axis=1)
        l2 = np.linalg.norm(c - b, axis=1)
        d = np.clip(np.linalg.norm(target - a, axis=1), np.abs(l1 - l2) + 1e-4, l1 + l2 - 1e-4)
        u, v = a - b, c - b
        cur = np.arccos(np.clip(np.sum(u * v, 1) / (l1 * l2), -1, 1))
        want = np.arccos(np.clip((l1 ** 2 + l2 ** 2 - d ** 2) / (2 * l1 * l2), -1, 1))
        normal = np.cross(u, v)
        nn = np.linalg.norm(normal, axis=1, keepdims=True)
        # a straight leg has no bending plane: bend about the hip's lateral axis (global X of the hip frame)
        normal = np.where(nn > 1e-9, normal / np.where(nn > 1e-9, nn, 1.0), glob[frames, hip][:, :, 0])
        knee_q = quat.from_rotvec(normal * (want - cur)[:, None])
        _local_update(rots, glob, frames, knee, knee_q)
        new_c = b + quat.rotate(knee_q, v)
        _local_update(rots, glob, frames, hip, _swing(new_c - a, target - a))
    return Motion(motion.skeleton, motion.fps, motion.root_positions_m, quat.canonical_sign(rots), motion.name)
