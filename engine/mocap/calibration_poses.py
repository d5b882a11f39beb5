"""The still calibration poses, built on an engine skeleton (the wizard asks for them; the evaluation simulates
them to calibrate orientation sensors: engine.mocap.orientation_calibration).

The static capture needs each segment's up direction *in the pose the subject really holds*
(``SegmentSpec.expected_up``). An engine skeleton's zero pose is the obvious candidate but is the wrong one for
the shipped CMU ASF skeleton (and Bandai after ``engine.mocap.rebase_to_tpose``): its zero pose is a T-pose, arms
out along +-X and legs splayed 20 deg. The standard set-up therefore asks for a **reference N-pose**, defined on
the skeleton itself (:func:`reference_npose`):

* trunk, neck, head and feet exactly as in the zero pose (upright, facing +Z, feet flat);
* each upper arm, forearm, thigh and shin pointing straight down (world -Y), reached from the zero pose by the
  *smallest* rotation of each bone in turn (shoulder, elbow, hip, knee). From a T-pose that is a rotation about
  the forward axis, so the arms hang straight along the body with the palms facing in, and the legs are straight
  with the feet under the hip joints;
* the ankles are counter-rotated so each foot keeps its zero-pose orientation (flat on the ground).

A frame of a shipped clip is not used: frame 0 of 16_01 (the subject standing before walking) has the elbows bent
~22 deg and the shins ~17 deg off vertical, i.e. it is not the pose the operator asks for.

Real takes start in whatever pose the athlete stands in (issue 29): an **A-pose** (:func:`reference_apose`) is the
N-pose with both straight arms swung out sideways in the frontal plane by the abduction angle (0 = the N-pose,
arms down; 90 = arms horizontal as in the T-pose; any angle between), the rest of the body as in the N-pose.
:func:`pose_rotations` builds every pose on any skeleton: one whose zero pose is not upright (raw Bandai) gets it
built on its T-pose re-based frames (engine.mocap.rest_pose) and mapped back into its own joint frames.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from engine.mocap.rest_pose import tpose_bases, tpose_skeleton
from engine.mocap.roles import joint_roles
from engine.mocap.rotations import minimal_rotation

UP = np.array([0.0, 1.0, 0.0])
POSES = ("npose", "tpose", "apose")
ARM_JOINTS = ("shoulder", "elbow")  # the joints whose segments an A-pose's arm angle moves (upper arm, forearm)
# (joint role, distal role) of each bone that hangs straight down in the N-pose, parents before children
_HANGING = tuple((f"{side}_{joint}", f"{side}_{distal}") for side in ("left", "right")
                 for joint, distal in (("shoulder", "elbow"), ("elbow", "wrist"), ("hip", "knee"), ("knee", "ankle")))
_MAX_TRUNK_TILT_DEG = 20.0


def _fk(skeleton: Any, local: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World positions (J, 3) and rotations (J, 3, 3) of local rotation matrices (J, 3, 3), root at the origin."""
    glob = np.empty_like(local)
    pos = np.zeros((skeleton.n_joints, 3))
    glob[0] = local[0]
    for j in range(1, skeleton.n_joints):
        p = skeleton.parents[j]
        glob[j] = glob[p] @ local[j]
        pos[j] = pos[p] + glob[p] @ skeleton.offsets_m[j]
    return pos, glob


def _zero_pose_tilt_deg(skeleton: Any) -> float:
    """Angle (degrees) of the spine (pelvis -> upper back) from vertical in the skeleton's zero pose."""
    roles = joint_roles(skeleton)
    pos, _ = _fk(skeleton, np.tile(np.eye(3), (skeleton.n_joints, 1, 1)))
    spine = pos[roles["upper_back"]] - pos[roles["pelvis"]]
    return float(np.degrees(np.arccos(np.clip(spine @ UP / np.linalg.norm(spine), -1.0, 1.0))))


def reference_npose(skeleton: Any) -> tuple[np.ndarray, np.ndarray]:
    """The reference N-pose (module docstring) of an engine skeleton: ``(local, global)`` joint rotation
    matrices, each (J, 3, 3); ``global`` is what ``segment_specs_from_placements(pose_rotations=)`` takes.

    Refuses (ValueError) a skeleton whose zero pose is not upright (e.g. raw Bandai, lying along X: rebase it
    with ``engine.mocap.rebase_to_tpose`` first), since "straight down" would then not be along the body."""
    roles = joint_roles(skeleton)
    local = np.tile(np.eye(3), (skeleton.n_joints, 1, 1))
    pos, glob = _fk(skeleton, local)
    tilt = _zero_pose_tilt_deg(skeleton)
    if tilt > _MAX_TRUNK_TILT_DEG:
        raise ValueError(f"the skeleton's zero pose is not upright (spine {tilt:.0f} deg from vertical): "
                         "re-base it to a T-pose (engine.mocap.rebase_to_tpose) before building the N-pose")
    feet = {j: glob[j].copy() for j in (roles["left_ankle"], roles["right_ankle"])}
    for joint_role, distal_role in _HANGING:
        j, d = roles[joint_role], roles[distal_role]
        bone = pos[d] - pos[j]
        glob_j = minimal_rotation(bone, -UP) @ glob[j]
        parent = skeleton.parents[j]
        local[j] = glob[parent].T @ glob_j
        pos, glob = _fk(skeleton, local)
    for j, world in feet.items():  # keep the feet flat: undo the leg's swing at the ankle
        local[j] = glob[skeleton.parents[j]].T @ world
    return local, _fk(skeleton, local)[1]


def reference_bow(skeleton: Any, bow_deg: float = 60.0) -> np.ndarray:
    """Global joint rotations (J, 3, 3) of a forward bow: the reference N-pose with the trunk (and everything it
    carries: head, arms) pitched ``bow_deg`` forward at the hips while the legs stay as they were. A second still
    pose for `courtside calibrate`: it inclines the pelvis and chest, whose heading one upright pose and walking
    cannot fix."""
    roles = joint_roles(skeleton)
    local, glob = reference_npose(skeleton)
    c, s = np.cos(np.radians(bow_deg)), np.sin(np.radians(bow_deg))
    pitch = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])  # about +X (left): up tips toward +Z (forward)
    legs = {j: glob[j].copy() for j in (roles["left_hip"], roles["right_hip"])}
    local = local.copy()
    local[0] = pitch @ local[0]
    bowed = _fk(skeleton, local)[1]
    for j, world in legs.items():  # the thighs keep hanging straight down: flex the hips instead
        local[j] = bowed[skeleton.parents[j]].T @ world
    return _fk(skeleton, local)[1]


def reference_long_sit(skeleton: Any) -> np.ndarray:
    """Global joint rotations (J, 3, 3) of a long sit: the reference N-pose with the trunk upright and both legs
    straight out in front, horizontal (hips flexed 90 deg), kneecaps and toes up. A second still pose for
    `courtside calibrate`: it lays the shank horizontal, so gravity then shows the shank's rotation about its
    own long axis, which is its heading while standing; walking sees it only through the leg's swing plane, which
    follows the actor's toe-out (6-24 deg off on stylised gait)."""
    roles = joint_roles(skeleton)
    local, glob = reference_npose(skeleton)
    c, s = np.cos(np.radians(-90.0)), np.sin(np.radians(-90.0))
    pitch = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])  # about +X (left): down (-Y) -> forward (+Z)
    local = local.copy()
    for side in ("left", "right"):  # the whole leg turns as one: only the hip's local rotation changes
        j = roles[f"{side}_hip"]
        local[j] = glob[skeleton.parents[j]].T @ pitch @ glob[j]
    return _fk(skeleton, local)[1]


def reference_apose(skeleton: Any, arm_deg: float) -> np.ndarray:
    """Global joint rotations (J, 3, 3) of an A-pose: the reference N-pose with each straight arm swung out
    sideways (about the forward axis, in the frontal plane) by ``arm_deg`` (0 = the N-pose, 90 = horizontal),
    everything the shoulder carries turning with it."""
    if not 0.0 <= arm_deg <= 180.0:
        raise ValueError(f"arm angle {arm_deg:g} deg: expected 0 (arms down) to 90 (horizontal), at most 180")
    roles = joint_roles(skeleton)
    local, glob = reference_npose(skeleton)
    local = local.copy()
    for side, sign in (("left", 1.0), ("right", -1.0)):  # left arm out to +X: about +Z; right: about -Z
        c, s = np.cos(np.radians(sign * arm_deg)), np.sin(np.radians(sign * arm_deg))
        swing = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        j = roles[f"{side}_shoulder"]
        local[j] = glob[skeleton.parents[j]].T @ swing @ glob[j]
    return _fk(skeleton, local)[1]


def pose_rotations(skeleton: Any, pose: str, arm_deg: float | None = None) -> np.ndarray:
    """Global joint rotations (J, 3, 3), in the skeleton's own joint frames, of the named calibration pose:
    ``"npose"`` (:func:`reference_npose`), ``"tpose"`` (the zero pose of the upright skeleton: a T-pose for CMU
    ASF and re-based skeletons) or ``"apose"`` with the arms ``arm_deg`` out (:func:`reference_apose`). A skeleton
    whose zero pose is not upright (raw Bandai) gets the pose of its T-pose re-based frames (G B_jᵀ per joint)."""
    if pose not in POSES:
        raise ValueError(f"unknown calibration pose {pose!r}; known: {', '.join(POSES)}")
    if pose == "apose" and arm_deg is None:
        raise ValueError("an A-pose needs its arm angle (degrees out from the arms-down N-pose)")
    if _zero_pose_tilt_deg(skeleton) > _MAX_TRUNK_TILT_DEG:
        bases = tpose_bases(skeleton)
        return pose_rotations(tpose_skeleton(skeleton, bases), pose, arm_deg) @ np.transpose(bases, (0, 2, 1))
    if pose == "npose":
        return reference_npose(skeleton)[1]
    if pose == "apose":
        return reference_apose(skeleton, float(arm_deg))
    return np.tile(np.eye(3), (skeleton.n_joints, 1, 1))
