"""Issue 29, one decided pose: the live HMM emits its decoded root and local joint rotations with the joints
their forward kinematics; it decodes a take as the batch reconstruction does, camera warp included (live =
offline); and every file written from its poses gives them back (known answer: FK of the BVH read back equals the
emitted / saved joints within 1 mm), for `courtside synthesize` (batch and --lag) and `courtside reconstruct`,
which writes the poses as decided (no foot IK applied to the file alone)."""
from __future__ import annotations

import numpy as np
import pytest

from engine.hmm.evaluation import reconstruct, train_model
from engine.hmm.features import imu_features
from engine.hmm.online_engine import HMMEngine
from engine.mocap import Motion, forward_kinematics, resample, standard_placements
from engine.stream.engines import drive_frames
from gateway.cli import main as courtside
from tests.engine.stream.decided_checks import MM, assert_synthesize_writes_the_saved_poses, bvh_joints

FRAMES = 60
RATE_HZ = 30.0  # HMMConfig.fps: at this rate the frames are the take's samples
IMUS = ("right_foot",)


def _walk(native_motions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The first FRAMES frames of walk 16_32: (acc (T, 1, 3) g, gyro (T, 1, 3) rad/s, a camera ground track (T, 2)
    m offset from the root, as a tracker's would be)."""
    walk = resample(native_motions[5], RATE_HZ)
    acc, gyro = imu_features(walk, standard_placements(walk.skeleton, IMUS))
    return acc[:FRAMES], gyro[:FRAMES], walk.root_positions_m[:FRAMES][:, [0, 2]] + 0.3


def test_the_engine_decodes_as_the_batch_reconstruction_camera_warp_included(native_motions):
    """Live = offline: pushed frame by frame with camera fixes (ground and heading), the engine's root and
    rotations are those of `engine.hmm.evaluation.reconstruct` on the whole take, and its joints their FK."""
    model = train_model([native_motions[i] for i in (2, 3, 4)], IMUS)
    skeleton = native_motions[0].skeleton
    acc, gyro, ground = _walk(native_motions)
    acc[20:23] = np.nan  # a dropout: no evidence, the chains move on their transitions (live and batch alike)
    heading = np.linspace(0.0, 0.6, FRAMES)
    heading[:5] = np.nan  # the first fix brings a position only
    poses = drive_frames(HMMEngine({model.config.imu_channels: model}, skeleton), acc, ground, heading,
                         gyro_rps=gyro)
    root, quats, _ = reconstruct(model, acc, gyro, skeleton.n_joints, np.zeros(3), np.array([1.0, 0, 0, 0]),
                                 ground, heading, skeleton)
    np.testing.assert_allclose(np.stack([p.root_m for p in poses]), root, atol=1e-9)
    rotations = np.stack([p.local_rotations for p in poses])
    np.testing.assert_allclose(rotations * np.sign(np.sum(rotations * quats, -1))[..., None], quats, atol=1e-9)
    joints = np.stack([p.joint_positions_m for p in poses])
    np.testing.assert_allclose(joints, forward_kinematics(Motion(skeleton, RATE_HZ, root, quats))[0], atol=1e-9)
    assert np.abs(joints[0, 0, [0, 2]] - ground[0]).max() < 1e-12  # the first fix places the root


def test_the_decoder_follows_the_camera_by_the_warp_rule_and_faces_the_hips_to_a_heading_fix(native_motions):
    """Frame by frame, the decoder's root is `engine.graph.warp.follow_camera`'s path for the same steps and fixes
    (the first fix places it); with the skeleton, a first heading fix turns the body so its hips face it."""
    from engine.graph.warp import RootWarp, follow_camera
    from engine.hmm.features import body_features
    from engine.hmm.pose_decoder import PoseDecoder
    from engine.mocap import heading_from_positions, joint_roles, pose_joint_positions

    walk = resample(native_motions[5], RATE_HZ)
    body = body_features(walk)[:FRAMES]
    joints = walk.skeleton.n_joints
    fixes = walk.root_positions_m[:FRAMES][:, [0, 2]] + 0.3
    fixes[:3] = np.nan
    heading = np.full(FRAMES, np.nan)
    decoder = PoseDecoder(joints, RATE_HZ, RootWarp())
    roots = np.stack([decoder.step(b, f)[0] for b, f in zip(body, fixes)])
    ground, _ = follow_camera(body[:, joints * 4: joints * 4 + 3][:, [0, 2]], np.r_[0.0, body[1:, -1]], (0j, 0.0),
                              fixes, heading, RootWarp(), RATE_HZ, reset=np.arange(FRAMES) == 3)
    np.testing.assert_allclose(roots[:, [0, 2]], ground, atol=1e-9)
    roles = joint_roles(walk.skeleton)
    decoder = PoseDecoder(joints, RATE_HZ, RootWarp(), walk.skeleton)
    pose = pose_joint_positions(walk.skeleton, *decoder.step(body[0], None, 1.0))
    assert heading_from_positions(pose[None], roles["left_hip"], roles["right_hip"])[0] == pytest.approx(1.0)


@pytest.mark.parametrize("lag", [None, "0.5"])
def test_synthesize_writes_the_saved_poses_as_bvh(native_motions, tmp_path, lag):
    """`synthesize --engine hmm -o OUT.bvh --save-poses P.npz`: the BVH read back is the saved poses (joints
    within 1 mm, same frames), with or without --lag (the HMM decides each frame at once)."""
    acc, gyro, ground = _walk(native_motions)
    take = tmp_path / "take.npz"
    np.savez(take, acc_g=acc, gyro_rps=gyro, fps=RATE_HZ, position_m=ground, sensor_names=np.array(IMUS))
    assert_synthesize_writes_the_saved_poses("hmm", take, tmp_path, lag, FRAMES - 5)


def test_reconstruct_writes_the_poses_the_engine_emits(native_motions, motions, tmp_path):
    """`reconstruct --method hmm` trains the paper's acc + gyro model on the clips and writes exactly the poses the
    live engine emits with it (FK of the BVH within 1 mm), camera following included."""
    from engine.graph.inputs import read_take
    from engine.reconstruct_cli import _take_gyro

    acc, gyro, ground = _walk(native_motions)
    take, out = tmp_path / "take.npz", tmp_path / "hmm.bvh"
    np.savez(take, acc_g=acc, gyro_rps=gyro, fps=RATE_HZ, position_m=ground, sensor_names=np.array(IMUS))
    assert courtside(["reconstruct", "--method", "hmm", "--input", str(take), "-o", str(out), "--sample",
                      "--quiet"]) == 0
    model = train_model(motions, IMUS)  # the shipped clips at 30 Hz, as --sample trains it
    frames = read_take(str(take), list(IMUS), RATE_HZ)  # the frames the command pushed
    obs = frames.obs
    poses = drive_frames(HMMEngine({model.config.imu_channels: model}, motions[0].skeleton), obs.acc_g,
                         obs.position_m, obs.heading_rad, gyro_rps=_take_gyro(str(take), frames.frame, RATE_HZ, IMUS))
    emitted = np.stack([p.joint_positions_m for p in poses])
    assert np.abs(bvh_joints(out) - emitted).max() < MM
