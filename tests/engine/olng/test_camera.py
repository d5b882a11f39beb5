"""OLNG and the hierarchical HMM with the overhead camera's position and heading (issue 11): the integrated root
is pulled onto the camera track, so the global error is the camera's, not metres of drift."""
from __future__ import annotations

import numpy as np

from engine.graph.warp import RootWarp
from engine.mocap import (SEED003_SENSORS, Motion, forward_kinematics, resample, root_heading, standard_placements,
                          virtual_accelerometers)
from engine.mocap.ground import wrap_angle

FULL = RootWarp(1.0, 1.0, 1e3, 1e3)  # pull all the way: the root must sit exactly on the camera track


def _truth(motion: Motion):
    pos, _ = forward_kinematics(motion)
    return motion.root_positions_m[:, [0, 2]], root_heading(motion, pos)


def test_olng_root_follows_the_camera(native_motions):
    from engine.olng.config import NeighbourhoodGraphConfig, KnowledgeBaseConfig, OLNGConfig
    from engine.olng.mocap_bridge import build_knowledge_base
    from engine.olng.reconstructor import OLNGReconstructor

    kb = build_knowledge_base([native_motions[i] for i in (2, 3, 4)], KnowledgeBaseConfig())
    test = resample(native_motions[5], kb.fps)
    acc = virtual_accelerometers(test, standard_placements(test.skeleton, SEED003_SENSORS))[:15]
    ground, heading = (a[:15] for a in _truth(test))
    config = OLNGConfig(graph=NeighbourhoodGraphConfig(k_neighbours=128, i_best=16))
    rec = OLNGReconstructor(kb, config, root_warp=FULL)
    poses = [rec.push(acc[t], ground[t], heading[t]) for t in range(len(acc))]
    root = np.array([p.root_pos_m[[0, 2]] for p in poses])
    assert np.abs(root - ground).max() < 1e-9
    world = np.stack([p.joints_world_m for p in poses])
    from engine.mocap import heading_from_positions, joint_roles
    roles = joint_roles(test.skeleton)
    body = heading_from_positions(world, roles["left_hip"], roles["right_hip"])
    assert np.abs(wrap_angle(body - heading)).max() < 1e-6
    # the default (bounded, partial) pull with a noisy camera stays within the camera's noise; without it the
    # integrated root drifts
    rng = np.random.default_rng(0)
    rec = OLNGReconstructor(kb, config)
    noisy = [rec.push(acc[t], ground[t] + rng.normal(0, 0.05, 2), heading[t] + rng.normal(0, 0.17))
             for t in range(len(acc))]
    err = np.linalg.norm(np.array([p.root_pos_m[[0, 2]] for p in noisy]) - ground, axis=1)
    assert err.mean() < 0.06


def test_hmm_root_follows_the_camera(native_motions):
    from engine.hmm.evaluation import reconstruct, to_motion, train_model
    from engine.hmm.features import imu_features

    model = train_model([native_motions[i] for i in (2, 3, 4)], imu_names=("right_foot",))
    test = resample(native_motions[5], model.fps)
    acc, gyro = imu_features(test, standard_placements(test.skeleton, ("right_foot",)))
    ground, heading = _truth(test)
    args = (model, acc, gyro, test.skeleton.n_joints, test.root_positions_m[0], test.rotations[0, 0])
    plain, _, _ = reconstruct(*args)
    root, quats, _ = reconstruct(*args, ground, heading, test.skeleton, FULL)
    assert np.abs(root[:, [0, 2]] - ground).max() < 1e-9
    out = to_motion(test.skeleton, model.fps, root, quats, foot_ik=False)
    assert np.abs(wrap_angle(root_heading(out) - heading)).max() < 1e-6
    assert np.array_equal(root[:, 1], plain[:, 1])  # the height and the pose are the HMM's own
    cam = ground.copy()
    cam[:10] = np.nan  # the take starts without a fix: the first one places the root
    root, _, _ = reconstruct(*args, cam, None, test.skeleton, FULL)
    assert np.abs(root[10:, [0, 2]] - ground[10:]).max() < 1e-9
