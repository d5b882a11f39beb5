"""engine.mocap Motions -> the ClipData arrays the graph builder works on.

Everything the graph needs per clip is derived here with engine.mocap: forward kinematics, foot contacts,
heading from the hips, and virtual accelerometers for the configured sensor placements -- at normal speed
and, for MSV, on the clip replayed at half speed (resampled to twice the rate, played at the graph rate) and
at double speed (every other frame, both phases).
"""
from __future__ import annotations

import numpy as np

from engine.mocap import (Motion, SensorPlacement, foot_contacts, forward_kinematics, resample, root_heading,
                          virtual_accelerometers)

from .clips import ClipData
from .config import GraphConfig


def _retimed(motion: Motion, root: np.ndarray, rotations: np.ndarray) -> Motion:
    """The given frames played back at `motion.fps` (a time warp, same skeleton)."""
    return Motion(motion.skeleton, motion.fps, root, rotations, motion.name)


def speed_variation_streams(motion: Motion, placements: list[SensorPlacement]) -> tuple[np.ndarray, np.ndarray]:
    """(acc_slow (2F-1, S, 3), acc_fast (F, S, 3)) in g: readings of the clip at half and at double speed."""
    doubled = resample(motion, 2.0 * motion.fps)
    slow = virtual_accelerometers(_retimed(motion, doubled.root_positions_m, doubled.rotations), placements)
    fast = np.empty((motion.n_frames, len(placements), 3))
    for phase in (0, 1):
        sub = _retimed(motion, motion.root_positions_m[phase::2], motion.rotations[phase::2])
        if sub.n_frames >= 3:
            fast[phase::2] = virtual_accelerometers(sub, placements)
        else:  # too short to difference: no double-speed reading, fall back to normal speed
            fast[phase::2] = virtual_accelerometers(motion, placements)[phase::2]
    return slow, fast


def clip_from_motion(motion: Motion, placements: list[SensorPlacement], config: GraphConfig,
                     label: str = "") -> ClipData:
    """One clip's arrays at the graph rate (resampling the motion if needed)."""
    if abs(motion.fps - config.fps) > 1e-6:
        motion = resample(motion, config.fps)
    if motion.n_frames < 3:
        raise ValueError(f"clip {motion.name!r} is too short ({motion.n_frames} frames at {config.fps} Hz)")
    pos, glob = forward_kinematics(motion)
    acc = virtual_accelerometers(motion, placements, fk=(pos, glob))
    slow, fast = speed_variation_streams(motion, placements) if config.msv else (None, None)
    return ClipData(name=motion.name, positions_m=pos, contacts=foot_contacts(motion, positions_m=pos),
                    heading_rad=root_heading(motion, pos), acc_g=acc, label=label, acc_slow_g=slow,
                    acc_fast_g=fast, local_rotations=motion.rotations, root_positions_m=motion.root_positions_m)


def clips_from_motions(motions: list[Motion], placements: list[SensorPlacement], config: GraphConfig,
                       labels: list[str] | None = None) -> list[ClipData]:
    """All clips (they must share one skeleton topology, as the graph's poses are compared joint by joint)."""
    if not motions:
        raise ValueError("no motions given")
    first = motions[0].skeleton
    for m in motions[1:]:
        if not m.skeleton.same_topology(first):
            raise ValueError(f"clip {m.name!r} has a different skeleton from {motions[0].name!r}")
    labels = labels or [""] * len(motions)
    return [clip_from_motion(m, placements, config, lab) for m, lab in zip(motions, labels)]


def mocap_sensor_model(skeleton, placements: list[SensorPlacement], fps: float):
    """A `graph.SensorModel`: the virtual accelerometers of a motion given as (root (K, 3), rotations (K, J, 4))."""
    def model(root_m: np.ndarray, rotations: np.ndarray) -> np.ndarray:
        return virtual_accelerometers(Motion(skeleton, fps, root_m, rotations), placements)
    return model
