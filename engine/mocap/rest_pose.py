"""Re-base a clip's joint frames so that its zero pose is an upright T-pose facing +Z.

Why: the zero (all-identity) pose is what sensor frames and mirroring are defined on. CMU ASF's zero pose
is already a T-pose, but CMU BVH hangs the arms down and Bandai's lies along X with a different frame per
bone, so `mirror` must refuse Bandai and sensor roll about the bone is not anatomical there.

How: give every joint a constant frame change B_j. With G'_j = G_j B_j the new offsets are
offset'_k = B_p^T offset_k and local rotations q'_j = B_p^T q_j B_j (root: q'_0 = q_0 B_0), which leaves
every joint position of every frame unchanged. B_p is chosen so the children's offsets point along
T-pose directions (spine and head up, arms out along ±X, legs down, feet forward): a weighted Kabsch fit
over all children for branching joints, the minimal rotation for single-child joints. Symmetric input
gives symmetric output, so the re-based clip mirrors exactly."""
from __future__ import annotations

import numpy as np

from engine.mocap import quaternions as quat
from engine.mocap.roles import joint_roles
from engine.mocap.rotations import minimal_rotation
from engine.mocap.skeleton import Motion, Skeleton

_UP, _DOWN, _FWD = np.array([0.0, 1, 0]), np.array([0.0, -1, 0]), np.array([0.0, 0, 1])


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _bone_direction(part: str, side: float, is_end: bool) -> np.ndarray:
    """T-pose world direction of the bone that ends at a joint of the given role part."""
    out = np.array([side, 0.0, 0.0])
    table = {
        "lower_back": _UP, "upper_back": _UP, "neck": _UP, "head": _UP, "pelvis": _UP,
        "clavicle": _unit(np.array([0.4 * side, 1.0, 0.0])),  # shoulder girdle: up and a little out
        "hip": _unit(np.array([side, -1.0, 0.0])), "knee": _DOWN, "ankle": _DOWN,
        "toe": _FWD if is_end else _unit(np.array([0.0, -1.0, 2.0])),
        "shoulder": out, "elbow": out, "wrist": out, "hand": out,
    }
    return table[part]


def tpose_directions(skeleton: Skeleton) -> np.ndarray:
    """(J, 3) T-pose world direction of the bone from each joint's parent to it (row 0 unused).

    A joint takes the role of itself or, failing that, of its nearest role ancestor (fingers follow the
    hand, CMU's upperneck follows the neck); joints between the pelvis and a hip (CMU's hip joints, whose
    offsets are zero or lateral) follow the hip below them."""
    roles = joint_roles(skeleton)
    role_of = {j: r for r, j in roles.items()}
    dirs = np.zeros((skeleton.n_joints, 3))
    for k in range(1, skeleton.n_joints):
        a = k
        while a not in role_of and a > 0:
            a = int(skeleton.parents[a])
        role = role_of.get(a, "pelvis")
        if role == "pelvis":  # e.g. CMU lhipjoint: classify by the hip below it
            below = [r for r, j in roles.items() if r.endswith("_hip") and _is_ancestor(skeleton, k, j)]
            role = below[0] if below else "pelvis"
        side = 1.0 if role.startswith("left") else -1.0
        part = role.split("_", 1)[1] if role.startswith(("left_", "right_")) else role
        if a != k and part == "toe":
            dirs[k] = _FWD
        else:
            dirs[k] = _bone_direction(part, side, bool(skeleton.end_site[k]))
    return dirs


def _is_ancestor(skeleton: Skeleton, a: int, j: int) -> bool:
    while j > a:
        j = int(skeleton.parents[j])
    return j == a


def _fit_rotation(desired: np.ndarray, actual: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Rotation B with B @ desired_i ≈ actual_i (unit vectors): weighted Kabsch, or the minimal rotation
    taking the weighted mean direction onto the actual one when the fit leaves the roll undetermined
    (a single child, or children that all point the same way)."""
    h = (actual * weights[:, None]).T @ desired
    u, sv, vt = np.linalg.svd(h)
    if sv[1] < 1e-6 * sv[0]:
        return minimal_rotation(weights @ desired, weights @ actual)
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    return u @ d @ vt


def tpose_bases(skeleton: Skeleton) -> np.ndarray:
    """(J, 3, 3) frame changes B_j: joint j's T-pose frame expressed in its original frame.

    A bone's direction fixes B_j only up to a roll about the bone; the roll is the minimal rotation from
    the file's own frame. That is anatomical when the file's zero pose is a T-pose (CMU ASF) or a simple
    arms-down pose (CMU BVH). Bandai's files turn some frames by quarter turns (right-side limbs 180 deg,
    spine 90 deg, feet 90 deg); there the roll of those segments is off by that fixed turn — the same in
    every Bandai clip, so database and test clips still agree. (Estimating roll from joint twist in the
    data was tried and rejected: humeral rotation during running averages ~45 deg, so it is not stable.)"""
    dirs = tpose_directions(skeleton)
    base = np.repeat(np.eye(3)[None], skeleton.n_joints, axis=0)
    for p in range(skeleton.n_joints):  # topological order: a leaf inherits its parent's final frame
        kids = [k for k in skeleton.children(p) if np.linalg.norm(skeleton.offsets_m[k]) > 1e-9]
        if not kids:
            base[p] = base[skeleton.parents[p]] if p > 0 else np.eye(3)
            continue
        actual = np.array([_unit(skeleton.offsets_m[k]) for k in kids])
        weights = np.array([np.linalg.norm(skeleton.offsets_m[k]) for k in kids])
        base[p] = _fit_rotation(dirs[kids], actual, weights)
    return base


def tpose_skeleton(skeleton: Skeleton, bases: np.ndarray | None = None) -> Skeleton:
    """The skeleton with offsets expressed in the T-pose frames (its zero pose is the T-pose)."""
    base = tpose_bases(skeleton) if bases is None else bases
    offsets = skeleton.offsets_m.copy()
    offsets[1:] = np.einsum("kji,kj->ki", base[skeleton.parents[1:]], skeleton.offsets_m[1:])
    return Skeleton(skeleton.names, skeleton.parents, offsets, skeleton.end_site)


def rebase_to_tpose(motion: Motion) -> Motion:
    """Same clip (identical joint positions every frame) with joint frames re-based so the zero pose is a
    T-pose facing +Z, Y up. Use before `mirror` on BVH skeletons (Bandai, CMU BVH)."""
    skel = motion.skeleton
    base = tpose_bases(skel)
    b_quat = quat.from_matrix(base)  # (J, 4)
    parent_b = np.concatenate([quat.identity((1,)), b_quat[skel.parents[1:]]])
    rotations = quat.multiply(quat.multiply(quat.conjugate(parent_b)[None], motion.rotations), b_quat[None])
    return Motion(tpose_skeleton(skel, base), motion.fps, motion.root_positions_m.copy(),
                  quat.canonical_sign(rotations), motion.name)
