"""Pose encoding near 180-degree joints and the standard skeleton (regressions found on Bandai data)."""
from __future__ import annotations

import numpy as np

from engine.mocap import Motion, Skeleton
from engine.olng.knowledge_base import KnowledgeBase
from engine.olng.mocap_bridge import retarget, standard_skeleton
from engine.olng.pose import fk_root_frame, pose_vectors, rotvec_to_quat

from .synthetic import RIG, SENSORS, make_clip, root_frame_positions


def test_joints_held_near_180_degrees_give_small_continuous_pose_vectors():
    """Hips flexed around +-180 deg (as Bandai's legs sit at rest): raw rotation vectors flip between +pi and -pi,
    reference-relative ones stay small, and FK from them reproduces the joint positions exactly."""
    clip = make_clip("walk", 1.0, 3.0)
    quats = clip.local_quats.copy()
    wobble = 0.05 * np.sin(np.arange(len(quats)) / 3.0)
    quats[:, 9] = rotvec_to_quat(np.stack([np.pi + wobble, 0 * wobble, 0 * wobble], axis=1))
    clip = type(clip)(quats, clip.root_pos_m, clip.acc_g, "flipped")
    raw, _ = pose_vectors(quats)
    assert np.ptp(raw[:, 27]) > 6.0                           # +pi / -pi flips in the raw encoding
    kb = KnowledgeBase.from_clips(RIG, SENSORS, [clip], fps=25.0)
    assert np.abs(kb.q[:, 27:30]).max() < 0.2                 # small deviations from the reference
    np.testing.assert_allclose(kb.x_m, root_frame_positions(clip), atol=1e-5)
    np.testing.assert_allclose(fk_root_frame(kb.rig, kb.q[:5].astype(float))[0], root_frame_positions(clip)[:5], atol=1e-5)


def test_standard_skeleton_ignores_the_root_offset():
    """Bandai stores metres of translation in the root's offset; it is not a bone and must not scale clips."""
    parents = np.array([-1, 0, 1])
    bones = np.array([[0.0, 0.0, 0.0], [0.0, -0.4, 0.0], [0.0, -0.4, 0.0]])
    a = Skeleton(("root", "knee", "ankle"), parents, bones + [[0.0, 0.94, -4.5], [0, 0, 0], [0, 0, 0]])
    b = Skeleton(("root", "knee", "ankle"), parents, bones * 1.2)
    rot = np.tile([1.0, 0.0, 0.0, 0.0], (4, 3, 1))
    ma = Motion(a, 25.0, np.tile([0.0, 0.9, 0.0], (4, 1)), rot, "a")
    mb = Motion(b, 25.0, np.tile([0.0, 0.9, 0.0], (4, 1)), rot, "b")
    std = standard_skeleton([ma, mb])
    np.testing.assert_allclose(np.linalg.norm(std.offsets_m[1:], axis=1), [0.44, 0.44])
    np.testing.assert_allclose(retarget(ma, std).root_positions_m[:, 1], 0.9 * 1.1)
