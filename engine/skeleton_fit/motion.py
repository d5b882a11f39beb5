"""Turn a fitted SkeletonModel replayed on marker trajectories into an engine.mocap Motion (→ BVH).

Why this shape: the BVH rest pose is the captured pose at a reference frame (the first frame where every
segment frame exists), so offsets are real bone vectors of this performer and no T-pose has to be invented.
Each joint's global rotation is its segment frame relative to that reference, G_j(t) = R_j(t) R_j(ref)ᵀ, and the
local rotation is G_parent(t)ᵀ G_j(t). Forward kinematics then reproduces the fitted joint centres up to the
segments' non-rigidity (tested).

Marker files are Z-up lab frames; the engine world is Y-up (docs/CONTRACTS.md), so positions and frames are
turned by the proper rotation (x, y, z) → (x, z, −y). Short marker gaps are filled by linear interpolation in
time before playback, because a BVH needs a pose in every frame.
"""
from __future__ import annotations

import numpy as np

from engine.mocap import Motion, Skeleton
from engine.mocap import quaternions as quat

from .frames import to_world
from .model import SkeletonModel

Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def fill_gaps(track: np.ndarray) -> np.ndarray:
    """(F,3) with NaN rows → linearly interpolated in time (held at the ends). All-NaN tracks stay NaN."""
    ok = ~np.isnan(track).any(axis=1)
    if ok.all() or not ok.any():
        return track
    frames = np.arange(len(track))
    return np.stack([np.interp(frames, frames[ok], track[ok, k]) for k in range(3)], axis=1)


def to_motion(model: SkeletonModel, markers: dict[str, np.ndarray], fps: float, z_up: bool = True, name: str = "") -> Motion:
    """Replay ``model`` on ``markers`` ({name: (F,3)} metres) and return the Motion (joints = segments followed by
    their landmarks; a segment hangs from its ``attach`` landmark when it has one)."""
    filled = {k: fill_gaps(np.asarray(v, dtype=float)) for k, v in markers.items()}
    frames = model.segment_frames(filled)
    centres = model.joint_positions(filled)
    turn = Z_UP_TO_Y_UP if z_up else np.eye(3)

    names: list[str] = []
    parents: list[int] = []
    positions: list[np.ndarray] = []  # (F,3) world (Y-up) per output joint
    rotations: list[np.ndarray | None] = []  # (F,3,3) global frame per output joint, None for end sites
    index: dict[str, int] = {}

    def add(name: str, parent: str | None, pos: np.ndarray, rot: np.ndarray | None) -> None:
        index[name] = len(names)
        names.append(name)
        parents.append(-1 if parent is None else index[parent])
        positions.append(pos @ turn.T)
        rotations.append(None if rot is None else turn @ rot)

    for seg, joint in zip(model.marker_set.segments, model.joints):
        frame = frames[seg.name]
        add(seg.name, seg.attach or seg.parent, centres[seg.name], frame[1])
        for landmark in seg.landmarks:
            point = to_world(joint.landmarks_local[landmark.name], *frame)
            add(landmark.name, landmark.parent or seg.name, point, None if landmark.end else frame[1])

    order = _preorder(parents)  # BVH nests children inside parents: joints must be in depth-first order
    remap = {old: new for new, old in enumerate(order)}
    names = [names[i] for i in order]
    parents = [-1 if parents[i] < 0 else remap[parents[i]] for i in order]
    positions = [positions[i] for i in order]
    rotations = [rotations[i] for i in order]

    valid = np.all([np.isfinite(r).all(axis=(1, 2)) for r in rotations if r is not None], axis=0)
    if not valid.any():
        raise ValueError("no frame has every segment frame defined (markers missing throughout?)")
    ref = int(np.argmax(valid))
    globals_: list[np.ndarray] = []
    for rot, par in zip(rotations, parents):
        globals_.append(rot @ rot[ref].T if rot is not None else globals_[par])
    # Offsets: the least-squares constant bone vector in the parent's rest frame over all valid frames
    # (mean of G_parentᵀ (P_j − P_parent)); exact when the fitted segments are rigid.
    offsets = np.zeros((len(names), 3))
    for j, par in enumerate(parents):
        if par >= 0:
            bone = np.einsum("fji,fj->fi", globals_[par], positions[j] - positions[par])
            offsets[j] = np.nanmean(bone[valid], axis=0)
    n_frames = len(positions[0])
    local = np.empty((n_frames, len(names), 4))
    for j, par in enumerate(parents):
        rel = globals_[j] if par < 0 else np.swapaxes(globals_[par], 1, 2) @ globals_[j]
        # frames where a segment is undefined (long gaps at the ends) keep the rest orientation
        rel = np.where(np.isfinite(rel).all(axis=(1, 2))[:, None, None], rel, np.eye(3))
        local[:, j] = quat.from_matrix(rel)
    root = np.where(np.isfinite(positions[0]), positions[0], positions[0][ref])
    end_site = np.array([r is None for r in rotations])
    skeleton = Skeleton(tuple(names), np.array(parents), offsets, end_site)
    return Motion(skeleton, float(fps), root, local, name)


def _preorder(parents: list[int]) -> list[int]:
    """Depth-first pre-order of a tree given as parent indices (root = the −1 entry), children in input order."""
    children: dict[int, list[int]] = {}
    for j, p in enumerate(parents):
        children.setdefault(p, []).append(j)
    order, stack = [], list(reversed(children[-1]))
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(children.get(j, [])))
    return order
