"""Engine adapters: the online decoder with a lag covering the take is the batch search; the start state is the
camera's first fix; OLNG output is put back on the take's frame grid."""
from __future__ import annotations

import numpy as np

from engine.evaluation import engines
from engine.evaluation.simulate import CameraModel, accelerometers, camera_track
from engine.evaluation.takes import chain_clips
from engine.graph.config import GraphConfig
from engine.graph.graph import build_from_clips
from engine.graph.mocap_adapter import clips_from_motions
from engine.graph.viterbi import SearchWeights
from engine.mocap import SEED000_SENSORS, forward_kinematics, root_heading, standard_placements


def _held_out_take(motions):
    """Clips 2 and 3 chained into a take and removed from the graph: (graph, take, accelerations, camera track)."""
    cfg = GraphConfig(msv=True, sensor_names=list(SEED000_SENSORS))
    clips = clips_from_motions(motions, standard_placements(motions[0].skeleton), cfg)
    graph = build_from_clips(clips, cfg).without_clips([2, 3])
    take = chain_clips(motions, [2, 3], [m.name for m in motions])
    acc, _ = accelerometers(take, SEED000_SENSORS, None, np.random.default_rng(0))
    return graph, take, acc, camera_track(take, CameraModel(), np.random.default_rng(1))


def test_fixed_lag_covering_the_take_equals_the_batch_search(motions):
    graph, take, acc, cam = _held_out_take(motions)
    for camera in (True, False):
        args = (graph, acc, (0, 1), cam.position_m, cam.heading_rad, SearchWeights(0.5, 1, 1), camera)
        batch = engines.motion_graph(*args)
        online = engines.motion_graph(*args, lag_s=take.duration_s + 1)
        assert np.allclose(batch.joints_m, online.joints_m, atol=1e-4)
        assert np.array_equal(batch.source_clip, online.source_clip)
        assert not np.isin(batch.source_clip, [2, 3]).any()


def test_start_state_is_the_first_camera_fix(motions):
    take = chain_clips(motions, [4], [m.name for m in motions], start_heading_rad=0.3)
    pos = np.array([[1.5, -2.0]])
    root, quat = engines.start_state(take, pos, np.array([1.0]))
    m = take.segments[0].motion
    placed = type(m)(m.skeleton, m.fps, root[None], np.concatenate([quat[None, None], m.rotations[:1, 1:]], 1))
    joints, _ = forward_kinematics(placed)
    assert np.allclose(joints[0, 0, [0, 2]], [1.5, -2.0]) and joints[0, 0, 1] == m.root_positions_m[0, 1]
    assert np.isclose(root_heading(placed, joints)[0], 1.0)


def test_resampled_outputs_land_on_the_take_grid(motions):
    take = chain_clips(motions, [0], [m.name for m in motions])
    times = np.arange(0, take.duration_s, 1 / 25)
    values = np.stack([times, 2 * times], axis=1)[:, None, :]  # (T25, 1, 2) linear in time
    out = engines.on_take_grid(values, times, take)
    t = np.minimum(np.arange(take.n_frames) / take.fps, times[-1])
    assert out.shape == (take.n_frames, 1, 2) and np.allclose(out[:, 0, 0], t) and np.allclose(out[:, 0, 1], 2 * t)


def test_with_the_camera_every_sensor_set_gets_the_same_fused_root(motions):
    """Root fusion: the motion graph's rows with the camera -- 6 or 1 accelerometers, or none -- stand on the same
    root (joint 0 on the ground, the hips' heading), so adding accelerometers cannot make it worse; without fusion
    they differ by centimetres. (The same to the bit as the search's output, engine/graph/test_root_fusion.py; here
    measured back from the placed float32 database poses: to 1e-6 m and 1e-4 rad.)"""
    from engine.evaluation.metrics import hips_heading
    from engine.graph.root_fusion import RootFusion
    from engine.graph.warp import RootWarp

    graph, take, acc, cam = _held_out_take(motions)
    for fusion, same in ((RootFusion(), True), (RootFusion.off(), False)):
        rows = [engines.motion_graph(graph, a, idx, cam.position_m, cam.heading_rad, w, True, RootWarp(),
                                     fusion=fusion).joints_m
                for a, idx, w in ((acc, tuple(range(6)), SearchWeights(0.5, 10, 3)),
                                  (acc, (1,), SearchWeights(0.5, 10, 3)), (None, (), SearchWeights(0.0, 10, 3)))]
        roots = [(j[:, 0, [0, 2]], hips_heading(j, take.skeleton)) for j in rows]
        pos = max(np.abs(r[0] - roots[0][0]).max() for r in roots[1:])
        head = max(np.abs(np.angle(np.exp(1j * (r[1] - roots[0][1])))).max() for r in roots[1:])
        assert (pos < 1e-6 and head < 1e-4) if same else pos > 1e-3


def test_fused_joints_stand_on_the_fused_root(motions):
    """Any engine's world joints (OLNG, HMM) are turned and moved onto the fused root exactly, pose unchanged."""
    from engine.evaluation.metrics import hips_heading
    from engine.graph.root_fusion import RootFusion, fuse_track

    take = chain_clips(motions, [4], [m.name for m in motions], start_heading_rad=0.3)
    cam = camera_track(take, CameraModel(), np.random.default_rng(2))
    joints = take.joints_m + [0.4, 0.0, -0.2]  # an engine 40 cm off the camera
    out = engines.fused_joints(joints, take, cam, RootFusion())
    ground, heading = fuse_track(RootFusion(), take.fps, cam.position_m, cam.heading_rad, joints[:, 0, [0, 2]],
                                 hips_heading(joints, take.skeleton))
    assert np.allclose(out[:, 0, [0, 2]], ground, atol=1e-9)
    assert np.allclose(np.angle(np.exp(1j * (hips_heading(out, take.skeleton) - heading))), 0, atol=1e-9)
    bone = np.linalg.norm(out[:, 1] - out[:, 0], axis=1)
    assert np.allclose(bone, np.linalg.norm(joints[:, 1] - joints[:, 0], axis=1))  # a rigid move per frame
    assert np.array_equal(engines.fused_joints(joints, take, cam, RootFusion.off()), joints)
