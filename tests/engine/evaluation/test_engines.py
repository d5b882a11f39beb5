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


def test_fixed_lag_covering_the_take_equals_the_batch_search(motions):
    cfg = GraphConfig(msv=True, sensor_names=list(SEED000_SENSORS))
    clips = clips_from_motions(motions, standard_placements(motions[0].skeleton), cfg)
    graph = build_from_clips(clips, cfg).without_clips([2, 3])
    take = chain_clips(motions, [2, 3], [m.name for m in motions])
    acc, _ = accelerometers(take, SEED000_SENSORS, None, np.random.default_rng(0))
    cam = camera_track(take, CameraModel(), np.random.default_rng(1))
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
