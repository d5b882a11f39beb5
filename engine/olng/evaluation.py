"""Leave-one-out evaluation of the OLNG on real clips (spec A3/A5 offline reproduction).

For each test clip: build the knowledge base from every OTHER clip (with the same augmentation), simulate the
four worn sensors on the test clip (engine.mocap virtual accelerometers, optionally perturbed by a
SensorErrorModel; for variants that search on them also the orientations a device reports, through an
`engine.mocap.orientation.OrientationErrorModel` -- per-sensor yaw offset and drift, tilt noise, misalignment --
and the angular rates), stream them through OLNGReconstructor, and score against the clip (engine.olng.metrics).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine import progress
from engine.mocap import (SEED003_SENSORS, Motion, SensorErrorModel, forward_kinematics, resample,
                          standard_placements, virtual_accelerometers, virtual_gyroscopes)
from engine.mocap.orientation import OrientationErrorModel, virtual_orientations
from engine.olng.config import KnowledgeBaseConfig, OLNGConfig
from engine.olng.metrics import ClipErrors, score
from engine.olng.knowledge_base import KnowledgeBase
from engine.graph.warp import RootWarp
from engine.olng.mocap_bridge import build_knowledge_base
from engine.olng.pose import quat_to_matrix, split_heading
from engine.olng.reconstructor import OLNGReconstructor


@dataclass(frozen=True)
class Variant:
    """One row of the table: a name, the reconstructor configuration and the IMU channels it searches on."""

    name: str
    config: OLNGConfig
    channels: tuple[str, ...] = ("acc",)


def simulate_readings(motion: Motion, kb: KnowledgeBase, error_model: SensorErrorModel | None,
                      rng: np.random.Generator) -> np.ndarray:
    """(F, 4, 3) readings in g of the seed-003 sensors worn by the performer of `motion` (on its own skeleton),
    optionally perturbed by a sensor error model."""
    if len(kb.sensors.bone) != len(SEED003_SENSORS):
        raise ValueError("evaluation supports the seed-003 four-sensor knowledge base")
    acc = virtual_accelerometers(motion, standard_placements(motion.skeleton, SEED003_SENSORS))
    return error_model.apply(acc, motion.fps, rng) if error_model is not None else acc


def simulate_orientation_channels(motion: Motion, error_model: OrientationErrorModel,
                                  rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(quat_wxyz (F, 4, 4) sensor -> device earth as `error_model` reports it, gyro_rps (F, 4, 3)) of the seed-003
    sensors on the performer of `motion`."""
    placements = standard_placements(motion.skeleton, SEED003_SENSORS)
    fk = forward_kinematics(motion)
    quats = error_model.apply(virtual_orientations(motion, placements, fk=fk), motion.fps, rng)
    return quats, virtual_gyroscopes(motion, placements, fk=fk)


def reconstruct(kb: KnowledgeBase, config: OLNGConfig, acc_g: np.ndarray, root_pos_m: np.ndarray,
                root_quat: np.ndarray, camera: tuple[np.ndarray, np.ndarray] | None = None,
                root_warp: RootWarp = RootWarp(), channels: tuple[str, ...] = ("acc",),
                quat_wxyz: np.ndarray | None = None, gyro_rps: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray, OLNGReconstructor]:
    """Stream a take; returns world joints (F, J, 3), root rotations (F, 3, 3) and the reconstructor (timings).
    `camera` = (ground (F, 2) m, body heading (F,) rad) per frame pulls the root onto the camera track;
    quat_wxyz (F, S, 4) / gyro_rps (F, S, 3) feed the orientation / gyro channels when ``channels`` names them."""
    rec = OLNGReconstructor(kb, config, root_warp, channels=channels)
    heading, _ = split_heading(root_quat[None])
    rec.reset_root(root_pos_m, float(heading[0]))
    none = [None] * len(acc_g)
    cam_pos, cam_head = camera if camera is not None else (none, none)
    quats = quat_wxyz if "orientation" in channels else none
    gyros = gyro_rps if "gyro" in channels else none
    poses = [rec.push(a, cam_pos[t], cam_head[t], quat_wxyz=quats[t], gyro_rps=gyros[t]) for t, a in enumerate(acc_g)]
    world = np.stack([p.joints_world_m for p in poses])
    root_rot = quat_to_matrix(np.stack([p.local_quats[0] for p in poses]))
    return world, root_rot, rec


def olng_leave_one_out(motions: list[Motion], test_indices: list[int], variants: list[Variant],
                  kb_config: KnowledgeBaseConfig = KnowledgeBaseConfig(), error_model: SensorErrorModel | None = None,
                  seed: int = 0, orientation_error: OrientationErrorModel = OrientationErrorModel.realistic()
                  ) -> dict[str, list[ClipErrors]]:
    """Scores per variant over the test clips, each reconstructed from a database without itself; variants
    searching on orientations get them through ``orientation_error`` (default: a realistic 6-axis filter)."""
    out: dict[str, list[ClipErrors]] = {v.name: [] for v in variants}
    for ti in progress.bar(test_indices, desc="olng leave-one-out", unit="clip"):
        kb = build_knowledge_base([m for i, m in enumerate(motions) if i != ti], kb_config)
        test = resample(motions[ti], kb.fps)
        acc = simulate_readings(test, kb, error_model, np.random.default_rng([seed, ti]))
        quats, gyro = simulate_orientation_channels(test, orientation_error, np.random.default_rng([seed, ti, 1]))
        true_world, true_rot = forward_kinematics(test)
        for v in variants:
            world, rot, _ = reconstruct(kb, v.config, acc, test.root_positions_m[0], test.rotations[0, 0],
                                        channels=v.channels, quat_wxyz=quats, gyro_rps=gyro)
            out[v.name].append(score(world, rot, true_world, true_rot[:, 0], test.skeleton))
    return out


def mean_pose_baseline(motions: list[Motion], test_indices: list[int], kb_config: KnowledgeBaseConfig = KnowledgeBaseConfig()) -> list[ClipErrors]:
    """The database's mean root-frame pose at the true root (what any reconstruction must beat)."""
    out = []
    for ti in test_indices:
        kb = build_knowledge_base([m for i, m in enumerate(motions) if i != ti], kb_config)
        test = resample(motions[ti], kb.fps)
        true_world, true_rot = forward_kinematics(test)
        mean_x = kb.x_m.mean(axis=0)
        world = test.root_positions_m[:, None] + np.einsum("fij,kj->fki", true_rot[:, 0], mean_x)
        out.append(score(world, true_rot[:, 0], true_world, true_rot[:, 0], test.skeleton))
    return out
