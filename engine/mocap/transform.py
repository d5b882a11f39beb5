"""Whole-clip transforms: resampling to another frame rate and left/right mirroring."""
from __future__ import annotations

import numpy as np

from engine.mocap import quaternions as quat
from engine.mocap.roles import left_right_pairs
from engine.mocap.skeleton import Motion


def resample(motion: Motion, fps: float) -> Motion:
    """Resample to `fps`: slerp for joint rotations, linear for the root position.

    Output frame k is at time k / fps, up to the last time the input covers. When the ratio is an integer
    (120 -> 30 Hz) the output is exactly every n-th input frame, with no filtering: mocap is already smooth
    at 120 Hz and the graph wants real poses, not averaged ones."""
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    if abs(fps - motion.fps) < 1e-9 * fps:
        return motion.slice(0)
    duration = (motion.n_frames - 1) / motion.fps
    n_out = int(np.floor(duration * fps + 1e-6)) + 1
    src = np.arange(n_out) * (motion.fps / fps)
    nearest = np.round(src)
    src = np.where(np.abs(src - nearest) < 1e-6, nearest, src)  # exact frames stay exact
    i0 = np.minimum(np.floor(src).astype(int), motion.n_frames - 1)
    i1 = np.minimum(i0 + 1, motion.n_frames - 1)
    frac = src - i0
    root = motion.root_positions_m[i0] * (1 - frac)[:, None] + motion.root_positions_m[i1] * frac[:, None]
    rots = quat.slerp(motion.rotations[i0], motion.rotations[i1], np.broadcast_to(frac[:, None], (n_out, motion.skeleton.n_joints)))
    return Motion(motion.skeleton, float(fps), root, quat.canonical_sign(rots), motion.name)


_REFLECT_X = np.diag([-1.0, 1.0, 1.0])


def check_mirror_symmetric(motion: Motion, max_angle_deg: float = 20.0) -> None:
    """Raise ValueError unless the rest pose is left/right symmetric about the X = 0 plane.

    Mirroring by reflecting every local rotation is only right when the zero pose is itself symmetric with
    the joint frames aligned to the world (CMU ASF and CMU BVH; Bandai only after `rebase_to_tpose`)."""
    skel = motion.skeleton
    pairs = left_right_pairs(skel)
    if not pairs:
        raise ValueError("skeleton has no left/right joint pairs to mirror")
    for left, right in pairs:
        a, b = _REFLECT_X @ skel.offsets_m[left], skel.offsets_m[right]
        na, nb = np.linalg.norm(a), np.linalg.norm(b)
        if na < 1e-9 and nb < 1e-9:
            continue
        cos = a @ b / max(na * nb, 1e-12)
        if cos < np.cos(np.radians(max_angle_deg)):
            raise ValueError(f"rest pose is not mirror-symmetric about X=0: {skel.names[left]!r} vs "
                             f"{skel.names[right]!r} offsets differ by {np.degrees(np.arccos(np.clip(cos, -1, 1))):.0f} deg "
                             "(re-base it first with engine.mocap.rebase_to_tpose)")


def mirror(motion: Motion) -> Motion:
    """Mirror across the world X = 0 plane (the sagittal plane of a skeleton facing +Z at rest), swapping
    left and right joints. Same skeleton, so mirrored clips can join the same database (seed 003 "M")."""
    check_mirror_symmetric(motion)
    rots = motion.rotations * np.array([1.0, 1.0, -1.0, -1.0])  # R -> S R S with S = diag(-1, 1, 1)
    swapped = rots.copy()
    for left, right in left_right_pairs(motion.skeleton):
        swapped[:, left], swapped[:, right] = rots[:, right], rots[:, left]
    root = motion.root_positions_m * np.array([-1.0, 1.0, 1.0])
    return Motion(motion.skeleton, motion.fps, root, swapped, motion.name + "_mirror")
