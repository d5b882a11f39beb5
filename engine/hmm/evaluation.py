"""From engine.mocap clips to a trained HMM, and leave-one-out scoring (spec B5, offline reproduction).

Behaviour labels (walk / run / jump / hop) come from the caller or, by default, from the clip itself: mean
ground speed above 2.2 m/s is a run, a root height range above 0.25 m at lower speed is a jump, else a walk.
"""
from __future__ import annotations

import numpy as np

from engine import progress
from engine.graph.evaluate import root_local
from engine.graph.warp import RootWarp
from engine.hmm.config import HMMConfig
from engine.hmm.features import (align_hemispheres, body_features, channel_set, imu_features, imu_orientations,
                                 stack_imu)
from engine.mocap.orientation import OrientationErrorModel
from engine.olng.channels import tilt_from_world
from engine.hmm.model import HierarchicalHMM, TrainingClip
from engine.hmm.phases import detect_events, label_phases, segments_from_labels
from engine.hmm.pose_decoder import PoseDecoder
from engine.hmm.reconstructor import HMMReconstructor
from engine.mocap import (Motion, SensorErrorModel, error_joint_indices, forward_kinematics, joint_roles, resample,
                          root_heading, standard_placements)
from engine.olng.metrics import ClipErrors, score
from engine.olng.pose import split_heading


def behaviour_of(motion: Motion) -> str:
    """walk / run / jump from the root trajectory (see module doc)."""
    root = motion.root_positions_m
    speed = np.linalg.norm(np.diff(root[:, [0, 2]], axis=0), axis=1).mean() * motion.fps
    if speed > 2.2:
        return "run"
    if np.ptp(root[:, 1]) > 0.25:
        return "jump"
    return "walk"


def training_clip(motion: Motion, imu_names: tuple[str, ...], behaviour: str, config: HMMConfig) -> TrainingClip:
    """Segment and featurise one clip (already at the model rate)."""
    positions, _ = forward_kinematics(motion)
    roles = joint_roles(motion.skeleton)
    heading = root_heading(motion, positions)
    forward = np.stack([np.sin(heading), np.zeros_like(heading), np.cos(heading)], axis=1)
    joints = {k: roles[k] for k in ("right_ankle", "right_toe", "left_ankle", "left_toe")}
    events = detect_events(positions, motion.fps, joints, forward, config.contact_height_m,
                           config.contact_speed_mps, config.contact_min_frames)
    segments = segments_from_labels(label_phases(events), config.max_segment_frames, config.min_segment_frames)
    placements = standard_placements(motion.skeleton, imu_names)
    acc, gyro = imu_features(motion, placements)
    err = error_joint_indices(motion.skeleton)
    align = root_local(positions[:, err], positions[:, 0, [0, 2]], heading).reshape(len(positions), -1)
    use_gyro, use_tilt = channel_set(config.imu_channels)
    imu = stack_imu(acc, gyro if use_gyro else None,
                    tilt_from_world(imu_orientations(motion, placements)) if use_tilt else None)
    return TrainingClip(body_features(motion), imu, align, segments, behaviour)


def train_model(motions: list[Motion], imu_names: tuple[str, ...] = ("right_foot",), labels: list[str] | None = None,
                config: HMMConfig = HMMConfig()) -> HierarchicalHMM:
    at_rate = [resample(m, config.fps) for m in motions]
    labels = labels or [behaviour_of(m) for m in at_rate]
    clips = [training_clip(m, imu_names, lab, config) for m, lab in zip(at_rate, labels)]
    for clip, body in zip(clips, align_hemispheres([c.body for c in clips])):
        clip.body = body
    return HierarchicalHMM.train(clips, config)


def reconstruct(model: HierarchicalHMM, acc_g: np.ndarray, gyro_rps: np.ndarray, joints: int, root0_m: np.ndarray,
                root_quat0: np.ndarray, camera_position_m: np.ndarray | None = None,
                camera_heading_rad: np.ndarray | None = None, skeleton=None,
                root_warp: RootWarp = RootWarp(), quat_wxyz: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray, list]:
    """Stream a take; returns (root positions (T, 3), local quaternions (T, J, 4), per-frame HMMFrame list).
    ``quat_wxyz`` (T, S, 4) sensor -> device earth: the tilt channel's input (models with "+tilt").

    The poses are decoded frame by frame by `PoseDecoder`, as the live engine decodes them, from the ground
    position of ``root0_m`` and the heading of ``root_quat0``. With the overhead camera's ground position (T, 2) m
    and/or body heading (T,) rad (NaN = no fix) the integrated root is pulled towards them frame by frame
    (engine/graph/warp.py; the first fix places it), so the global error is the camera's instead of metres of
    drift; `skeleton` (needed for the heading) gives the offset between the root's twist and where the hips
    face."""
    rec = HMMReconstructor(model)
    heading0, _ = split_heading(root_quat0[None])
    decoder = PoseDecoder(joints, model.fps, root_warp, skeleton, np.asarray(root0_m, float)[[0, 2]],
                          float(heading0[0]))
    quats = [None] * len(acc_g) if quat_wxyz is None else quat_wxyz
    frames, roots, rotations = [], [], []
    for t, (a, g, q) in enumerate(zip(acc_g, gyro_rps, quats)):
        frames.append(rec.push(a, g, q))
        root, rots = decoder.step(frames[-1].body, None if camera_position_m is None else camera_position_m[t],
                                  None if camera_heading_rad is None else camera_heading_rad[t])
        roots.append(root)
        rotations.append(rots)
    return np.stack(roots), np.stack(rotations), frames


def to_motion(skeleton, fps: float, root_m: np.ndarray, quats: np.ndarray, foot_ik: bool = True, name: str = "") -> Motion:
    """Reconstructed frames as a Motion; with foot_ik the ankles are pinned during the output's own foot
    contacts by engine.graph's two-bone IK (the paper's Kim et al. clean-up against foot sliding)."""
    motion = Motion(skeleton, fps, root_m, quats, name)
    if not foot_ik:
        return motion
    from engine.graph.postprocess import fix_foot_skate
    from engine.mocap import foot_contacts

    return fix_foot_skate(motion, foot_contacts(motion))


def hmm_leave_one_out(motions: list[Motion], test_indices: list[int], imu_names: tuple[str, ...] = ("right_foot",),
                  error_model: SensorErrorModel | None = None, seed: int = 0, labels: list[str] | None = None,
                  train_indices: list[int] | None = None, config: HMMConfig = HMMConfig(),
                  foot_ik: bool = False,
                  orientation_error: OrientationErrorModel = OrientationErrorModel.realistic()) -> list[ClipErrors]:
    """Per test clip: train on the other clips (or `train_indices` minus the test clip), simulate the IMUs on
    the held-out clip (orientations, for a "+tilt" model, through ``orientation_error``: a real device's yaw
    offset, drift, tilt noise and misalignment), reconstruct, score. Joint error is with the root translation
    removed, as in the paper. Scored as decided, as the live engine emits it and `courtside reconstruct` writes it
    (issue 29: one pose); ``foot_ik`` scores the batch foot-skate clean-up on top, which only a whole take allows."""
    out = []
    pool = list(range(len(motions))) if train_indices is None else train_indices
    for ti in progress.bar(test_indices, desc="hmm leave-one-out", unit="clip"):
        train = [i for i in pool if i != ti]
        model = train_model([motions[i] for i in train], imu_names, [labels[i] for i in train] if labels else None, config)
        test = resample(motions[ti], config.fps)
        placements = standard_placements(test.skeleton, imu_names)
        acc, gyro = imu_features(test, placements)
        if error_model is not None:
            acc = error_model.apply(acc, test.fps, np.random.default_rng([seed, ti]))
        device = None
        if channel_set(config.imu_channels)[1]:
            device = orientation_error.apply(imu_orientations(test, placements), test.fps,
                                             np.random.default_rng([seed, ti, 1]))
        root, quats, _ = reconstruct(model, acc, gyro, test.skeleton.n_joints, test.root_positions_m[0],
                                     test.rotations[0, 0], quat_wxyz=device)
        pred = to_motion(test.skeleton, test.fps, root, quats, foot_ik)
        pw, pr = forward_kinematics(pred)
        tw, tr = forward_kinematics(test)
        out.append(score(pw, pr[:, 0], tw, tr[:, 0], test.skeleton))
    return out
