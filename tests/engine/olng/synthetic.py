"""Procedural motion with exact answers for the OLNG tests: a 15-joint Y-up skeleton facing +Z, a parametric
gait (speed-dependent frequency and amplitudes) and jumping jacks, and exact virtual accelerometers
(finite differences of the FK tip positions, gravity added, rotated into the sensor frames)."""
from __future__ import annotations

import numpy as np

from engine.olng.knowledge_base import ClipArrays, SensorRig
from engine.olng.pose import Rig, fk_root_frame, quat_to_matrix, rotvec_to_quat

G = 9.80665
NAMES = ("root", "spine", "head", "lshoulder", "lelbow", "lwrist", "rshoulder", "relbow", "rwrist",
         "lhip", "lknee", "lankle", "rhip", "rknee", "rankle")
PARENTS = np.array([-1, 0, 1, 1, 3, 4, 1, 6, 7, 0, 9, 10, 0, 12, 13])
OFFSETS = np.array([
    [0, 0, 0], [0, 0.25, 0], [0, 0.3, 0],
    [0.18, 0.2, 0], [0.28, 0, 0], [0.25, 0, 0],
    [-0.18, 0.2, 0], [-0.28, 0, 0], [-0.25, 0, 0],
    [0.1, -0.05, 0], [0, -0.42, 0], [0, -0.42, 0],
    [-0.1, -0.05, 0], [0, -0.42, 0], [0, -0.42, 0],
], dtype=float)
RIG = Rig(NAMES, PARENTS, OFFSETS)


def _frame(x_axis, z_axis) -> np.ndarray:
    x, z = np.asarray(x_axis, float), np.asarray(z_axis, float)
    return np.stack([x, np.cross(z, x), z], axis=1)


# [LW, RW, LA, RA]: forearm sensors (X distal, Z up in T-pose), shank sensors (X distal = down, Z forward)
SENSORS = SensorRig(
    bone=np.array([4, 7, 10, 13]),
    local_rot=np.stack([_frame([1, 0, 0], [0, 1, 0]), _frame([-1, 0, 0], [0, 1, 0]),
                        _frame([0, -1, 0], [0, 0, 1]), _frame([0, -1, 0], [0, 0, 1])]),
    tip=np.array([5, 8, 11, 14]),
)


def gait_rotvecs(phase: np.ndarray, amplitude: float) -> np.ndarray:
    """Local rotation vectors (F, J, 3) of a walk/run cycle at the given phase (rad)."""
    f = len(phase)
    rv = np.zeros((f, len(NAMES), 3))
    s, c = np.sin(phase), np.cos(phase)
    rv[:, 0] = np.stack([0.05 * amplitude * np.sin(2 * phase), 0.1 * s, 0.03 * c], -1)   # root tilt + sway
    rv[:, 1, 1] = -0.15 * amplitude * s                                                    # spine twist
    rv[:, 3] = np.stack([0.6 * amplitude * s, 0 * s, -1.2 + 0 * s], -1)                    # arms down + swing
    rv[:, 6] = np.stack([-0.6 * amplitude * s, 0 * s, 1.2 + 0 * s], -1)
    rv[:, 4, 1] = -0.3 - 0.5 * amplitude * (1 + s) / 2                                     # elbows
    rv[:, 7, 1] = 0.3 + 0.5 * amplitude * (1 - s) / 2
    rv[:, 9, 0] = -0.5 * amplitude * s                                                     # hips flex
    rv[:, 12, 0] = 0.5 * amplitude * s
    rv[:, 10, 0] = 0.9 * amplitude * (1 - np.cos(phase + 0.8)) / 2                         # knees
    rv[:, 13, 0] = 0.9 * amplitude * (1 - np.cos(phase + 0.8 + np.pi)) / 2
    return rv


def jacks_rotvecs(phase: np.ndarray) -> np.ndarray:
    """Jumping jacks: arms from down to overhead and legs apart, in phase."""
    rv = np.zeros((len(phase), len(NAMES), 3))
    open_ = (1 - np.cos(phase)) / 2
    rv[:, 3, 2] = -1.3 + 2.4 * open_
    rv[:, 6, 2] = 1.3 - 2.4 * open_
    rv[:, 9, 2] = 0.35 * open_
    rv[:, 12, 2] = -0.35 * open_
    rv[:, 10, 0] = 0.3 * np.sin(2 * phase) ** 2
    rv[:, 13, 0] = 0.3 * np.sin(2 * phase) ** 2
    return rv


def make_clip(kind: str, speed: float, seconds: float, fps: float = 25.0, phase0: float = 0.0,
              speed_profile=None, name: str = "") -> ClipArrays:
    """A clip of `kind` ('walk' or 'jacks') at a tempo factor `speed` (or a callable speed(t_s))."""
    frames = int(round(seconds * fps))
    t = np.arange(frames) / fps
    rate = np.full(frames, speed) if speed_profile is None else speed_profile(t)
    phase = phase0 + 2 * np.pi * 1.0 * np.concatenate([[0.0], np.cumsum(rate[:-1]) / fps])
    if kind == "walk":
        rv = gait_rotvecs(phase, amplitude=0.6 + 0.4 * speed)
        forward = np.concatenate([[0.0], np.cumsum(1.2 * rate[:-1]) / fps])
        root = np.stack([0 * t, 0.92 + 0.02 * np.cos(2 * phase), forward], -1)
    elif kind == "jacks":
        rv = jacks_rotvecs(phase)
        root = np.stack([0 * t, 0.92 + 0.08 * np.sin(phase) ** 2, 0 * t], -1)
    else:
        raise ValueError(kind)
    quats = rotvec_to_quat(rv)
    return ClipArrays(quats, root, simulate_acc_g(quats, root, fps), name or f"{kind}-{speed}")


def world_positions(quats: np.ndarray, root: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World joint positions (F, J, 3) and joint rotations (F, J, 3, 3)."""
    from engine.olng.pose import pose_vectors

    q, _ = pose_vectors(quats)
    pos, rot = fk_root_frame(RIG, q)
    root_rot = quat_to_matrix(quats[:, 0])           # full root rotation; fk_root_frame is relative to it
    world = root[:, None] + np.einsum("fij,fkj->fki", root_rot, pos)
    return world, root_rot[:, None] @ rot


def simulate_acc_g(quats: np.ndarray, root: np.ndarray, fps: float) -> np.ndarray:
    """Exact virtual accelerometers at the sensor tips: R_s^T (p'' + g up) / g, shape (F, 4, 3)."""
    world, rot = world_positions(quats, root)
    p = world[:, SENSORS.tip]
    acc = np.empty_like(p)
    acc[1:-1] = (p[2:] - 2 * p[1:-1] + p[:-2]) * fps**2
    acc[0], acc[-1] = acc[1], acc[-2]
    acc[..., 1] += G
    sensor_rot = rot[:, SENSORS.bone] @ SENSORS.local_rot
    return np.einsum("fsji,fsj->fsi", sensor_rot, acc) / G


def root_frame_positions(clip: ClipArrays) -> np.ndarray:
    from engine.olng.pose import pose_vectors

    q, _ = pose_vectors(clip.local_quats)
    return fk_root_frame(RIG, q)[0]
