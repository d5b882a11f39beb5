"""From `engine.mocap` clips to the OLNG's arrays: standard skeleton, augmentation, virtual sensors (spec A2.1-A2.2).

WHY a bridge: the OLNG core works on plain arrays (tested on procedural motion with exact answers); this module
is the only place that knows about Motion/Skeleton, so readers and sensor models stay owned by engine.mocap.
"""
from __future__ import annotations

import numpy as np

from engine.mocap import (SEED003_SENSORS, Motion, SensorPlacement, Skeleton, forward_kinematics, joint_roles, mirror,
                          resample, standard_placements, virtual_accelerometers, virtual_gyroscopes)
from engine.mocap.orientation import virtual_orientations
from engine.olng.channels import tilt_from_world
from engine.olng.yaw import device_yaw
from engine.mocap.orientation import to_device_earth
from engine.olng.config import KnowledgeBaseConfig
from engine.olng.knowledge_base import ClipArrays, KnowledgeBase, SensorRig
from engine.olng.pose import Rig


def rig_from_skeleton(skeleton: Skeleton) -> Rig:
    return Rig(tuple(skeleton.names), np.asarray(skeleton.parents), np.asarray(skeleton.offsets_m), np.asarray(skeleton.end_site))


def skeleton_from_rig(rig: Rig) -> Skeleton:
    return Skeleton(rig.names, rig.parents, rig.offsets_m, rig.end_site)


def _tip_joint(skeleton: Skeleton, placement: SensorPlacement) -> int:
    """The joint next to a sensor whose position the control term predicts: a same-named role (wrist/ankle
    sensors sit next to the wrist/ankle joint), else the child of the sensor's joint along its offset."""
    roles = joint_roles(skeleton)
    if placement.name in roles:
        return roles[placement.name]
    children = skeleton.children(placement.joint)
    if not children:
        return placement.joint
    offsets = skeleton.offsets_m[children]
    return children[int(np.argmax(offsets @ placement.offset_m))]


def sensor_rig(skeleton: Skeleton, names: tuple[str, ...] = SEED003_SENSORS) -> tuple[SensorRig, list[SensorPlacement]]:
    """SensorRig for the named standard placements (paper: wrists and ankles, order [LW, RW, LA, RA])."""
    placements = standard_placements(skeleton, names)
    rig = SensorRig(
        bone=np.array([p.joint for p in placements]),
        local_rot=np.stack([p.rotation for p in placements]),
        tip=np.array([_tip_joint(skeleton, p) for p in placements]),
    )
    return rig, placements


def standard_skeleton(motions: list[Motion]) -> Skeleton:
    """Average bone lengths over all clips (the paper's "standard skeleton"); offsets keep the first clip's
    directions. Clips must share one topology."""
    first = motions[0].skeleton
    for m in motions[1:]:
        if not m.skeleton.same_topology(first):
            raise ValueError(f"clip {m.name!r} has a different skeleton topology from {motions[0].name!r}")
    lengths = np.mean([np.linalg.norm(m.skeleton.offsets_m, axis=1) for m in motions], axis=0)
    norms = np.linalg.norm(first.offsets_m, axis=1)
    offsets = np.where(norms[:, None] > 0, first.offsets_m / np.maximum(norms, 1e-12)[:, None] * lengths[:, None], 0.0)
    offsets[0] = first.offsets_m[0]   # the root's offset is not a bone (Bandai stores metres of translation there)
    return Skeleton(first.names, first.parents, offsets, first.end_site)


def _bone_length_sum(skeleton: Skeleton) -> float:
    return float(np.linalg.norm(skeleton.offsets_m[1:], axis=1).sum())


def retarget(motion: Motion, skeleton: Skeleton) -> Motion:
    """Same joint rotations on another skeleton of the same topology; root path scaled by the leg-length ratio."""
    scale = _bone_length_sum(skeleton) / max(_bone_length_sum(motion.skeleton), 1e-12)
    return Motion(skeleton, motion.fps, motion.root_positions_m * scale, motion.rotations, motion.name)


def reverse(motion: Motion) -> Motion:
    """Time-reversed copy (the paper's "R" augmentation)."""
    return Motion(motion.skeleton, motion.fps, motion.root_positions_m[::-1].copy(), motion.rotations[::-1].copy(),
                  motion.name + "_reverse")


def scaled(motion: Motion, factor: float) -> Motion:
    """The same motion performed by a uniformly larger/smaller actor (bones and root path scaled)."""
    return Motion(motion.skeleton.scaled(factor), motion.fps, motion.root_positions_m * factor, motion.rotations,
                  f"{motion.name}_x{factor:g}")


def augment(motions: list[Motion], config: KnowledgeBaseConfig) -> list[Motion]:
    """Resample to the knowledge-base rate, retarget to the standard skeleton, then add the requested copies.
    Mirroring needs a mirror-symmetric rest pose (engine.mocap.mirror raises a ValueError naming the joints)."""
    skeleton = standard_skeleton(motions)
    base = [retarget(resample(m, config.fps), skeleton) for m in motions]
    out = list(base)
    if config.mirror:
        out += [mirror(m) for m in base]
    if config.reverse:
        out += [reverse(m) for m in list(out)]
    return out


def clip_arrays(motion: Motion, placements: list[SensorPlacement]) -> ClipArrays:
    """Readings are simulated from the (augmented) motion itself, as spec A2.1 recommends: accelerations, and
    each sensor's tilt, yaw and angular rate (orientation / gyro channels, `engine.olng.channels`), from one FK."""
    fk = forward_kinematics(motion)
    quats = virtual_orientations(motion, placements, fk=fk)
    return ClipArrays(motion.rotations, motion.root_positions_m, virtual_accelerometers(motion, placements, fk=fk),
                      motion.name, tilt=tilt_from_world(quats), gyro_rps=virtual_gyroscopes(motion, placements, fk=fk),
                      yaw_rad=device_yaw(to_device_earth(quats, 0.0)))


def build_knowledge_base(motions: list[Motion], config: KnowledgeBaseConfig = KnowledgeBaseConfig(),
                         sensor_names: tuple[str, ...] = SEED003_SENSORS, scales: tuple[float, ...] = (1.0,)) -> KnowledgeBase:
    """The OLNG database from clips (any rate, one topology). `scales` adds resized-actor copies (Fig. 10b);
    FK and the energy use the unscaled standard skeleton, the readings come from each copy's own size."""
    clips = augment(motions, config)
    skeleton = clips[0].skeleton
    sensors, placements = sensor_rig(skeleton, sensor_names)
    arrays = []
    for factor in scales:
        for m in clips:
            copy = m if factor == 1.0 else scaled(m, factor)
            arrays.append(clip_arrays(copy, placements))
    return KnowledgeBase.from_clips(rig_from_skeleton(skeleton), sensors, arrays, config.fps)


