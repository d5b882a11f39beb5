"""Issue 29, one decided pose: the OLNG engine emits its root and local joint rotations with the joints their
forward kinematics, and every file written from them gives those joints back (known answer: FK of the BVH read
back equals the emitted / saved joints within 1 mm), for `courtside synthesize` (batch and --lag) and
`courtside reconstruct`."""
from __future__ import annotations

import numpy as np
import pytest

from engine.mocap import (SEED003_SENSORS, resample, standard_placements,
                          virtual_accelerometers)
from engine.stream.engines import drive_frames
from gateway.cli import main as courtside
from tests.engine.stream.decided_checks import MM, assert_synthesize_writes_the_saved_poses, bvh_joints

FRAMES = 50
KB_RATE_HZ = 25.0  # KnowledgeBaseConfig.fps


def _take(native_motions, path, fps: float = KB_RATE_HZ) -> tuple[np.ndarray, np.ndarray]:
    """The first FRAMES frames of walk 16_32 at ``fps`` as a synthesis-input take with a camera track: (acc (T,
    S, 3) g, camera ground positions (T, 2) m). At the knowledge base's rate the frames are the take's samples."""
    walk = resample(native_motions[5], fps)
    acc = virtual_accelerometers(walk, standard_placements(walk.skeleton, SEED003_SENSORS))[:FRAMES]
    ground = walk.root_positions_m[:FRAMES][:, [0, 2]] + 0.3
    np.savez(path, acc_g=acc, fps=fps, position_m=ground, sensor_names=np.array(SEED003_SENSORS))
    return acc, ground


def test_the_engine_emits_the_reconstruction_as_rotations_whose_fk_are_its_joints(native_motions):
    """The emitted pose is the reconstructor's (root, local quaternions) unchanged, on the spec's skeleton, and its
    joints are the reconstructor's world joints (the FK of the same rotations), through a dropout too."""
    from engine.olng.online_engine import build_spec
    from engine.olng.reconstructor import OLNGReconstructor

    spec = build_spec([native_motions[i] for i in (1, 2, 3, 4, 6)], "five clips")
    assert spec.skeleton is not None and np.array_equal(spec.parents, spec.skeleton.parents)
    walk = resample(native_motions[5], spec.rate_hz)
    acc = virtual_accelerometers(walk, standard_placements(walk.skeleton, SEED003_SENSORS))[:FRAMES]
    acc[20:23] = np.nan  # a dropout: the engine holds the last reading, as the reconstructor does
    engine = spec.make(0.0)
    poses = drive_frames(engine, acc)
    reference = OLNGReconstructor(engine.rec.kb, engine.rec.config)
    for pose, a in zip(poses, acc):
        own = reference.push(a)
        np.testing.assert_allclose(pose.root_m, own.root_pos_m, atol=1e-12)
        np.testing.assert_allclose(pose.local_rotations, own.local_quats, atol=1e-12)
        np.testing.assert_allclose(pose.joint_positions_m, own.joints_world_m, atol=1e-9)
    assert len(poses) == FRAMES


@pytest.mark.parametrize("lag", [None, "0.5"])
def test_synthesize_writes_the_saved_poses_as_bvh(native_motions, tmp_path, lag):
    """`synthesize --engine olng -o OUT.bvh --save-poses P.npz`: the BVH read back is the saved poses (joints
    within 1 mm, same frames), with or without --lag (OLNG decides each frame at once)."""
    take = tmp_path / "take.npz"
    _take(native_motions, take)
    assert_synthesize_writes_the_saved_poses("olng", take, tmp_path, lag, FRAMES - 5)


def test_reconstruct_writes_the_poses_the_engine_emits(native_motions, tmp_path):
    """`reconstruct --method olng` runs the live engine with its --k / --i-best / --window and writes exactly
    the poses it emits, camera following included (FK of the BVH within 1 mm)."""
    from engine.olng.config import NeighbourhoodGraphConfig, OLNGConfig
    from engine.olng.knowledge_base import KnowledgeBase
    from engine.olng.online_engine import OLNGEngine

    from engine.graph.inputs import load_take

    take, kb, out = tmp_path / "take.npz", tmp_path / "kb.npz", tmp_path / "olng.bvh"
    _take(native_motions, take)
    assert courtside(["reconstruct", "--method", "olng", "--input", str(take), "-o", str(out), "--sample",
                      "--save-kb", str(kb), "--k", "256", "--i-best", "16", "--quiet"]) == 0
    obs = load_take(str(take), list(SEED003_SENSORS), KB_RATE_HZ)  # the frames the command pushed
    config = OLNGConfig(graph=NeighbourhoodGraphConfig(k_neighbours=256, i_best=16, window=32))
    poses = drive_frames(OLNGEngine(KnowledgeBase.load(kb), config=config), obs.acc_g, obs.position_m,
                         obs.heading_rad)
    emitted = np.stack([p.joint_positions_m for p in poses])
    assert np.abs(bvh_joints(out) - emitted).max() < MM
    # the root followed the camera (placed on the first fix, then the bounded warp)
    assert np.abs(emitted[:, 0, [0, 2]] - obs.position_m).max() < 0.5
