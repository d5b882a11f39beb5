"""Windowed synthesis in the console's worker thread: live-rate batches in, the engine's poses out.

Ground truth: a shipped clip that is in the graph, streamed noise-free as virtual accelerometers at 100 Hz.
The fixed-lag Viterbi must then recover that clip's own poses, so joint heights match the clip's FK."""
from __future__ import annotations

import time

import numpy as np
import pytest

from engine.mocap import SEED000_SENSORS, forward_kinematics, load_clip, sample_clips, standard_placements, virtual_accelerometers
from gui.engine_link import GRAPH_FPS, load_or_build_graph, synthesis_setup
from gui.synthesis import SynthesisWorker

LIVE_HZ = 100.0


@pytest.fixture(scope="module")
def graph_and_clip(tmp_path_factory):
    graph, skeleton, _ = load_or_build_graph(cache_dir=tmp_path_factory.mktemp("graphs"))
    motion = load_clip(sample_clips()["16_11"], fps=GRAPH_FPS)
    acc = virtual_accelerometers(motion, standard_placements(motion.skeleton, SEED000_SENSORS))
    truth, _ = forward_kinematics(motion)
    return graph, skeleton, acc, truth


def test_graph_cache_round_trip(tmp_path):
    g1, _, path = load_or_build_graph(cache_dir=tmp_path)
    assert path.is_file()
    g2, _, path2 = load_or_build_graph(cache_dir=tmp_path)
    assert path2 == path and g2.n_nodes == g1.n_nodes and np.array_equal(g2.edge_src, g1.edge_src)


def test_worker_recovers_clip_poses_from_live_batches(graph_and_clip):
    graph, skeleton, acc30, truth = graph_and_clip
    sensors = [("st0", k) for k in range(graph.n_sensors)]
    setup = synthesis_setup(graph, skeleton, sensors, lag_s=0.5)
    worker = SynthesisWorker(setup.make_synthesizer, setup.sensors, setup.rate_hz, setup.lag_s)
    worker.start()
    t0 = 100.0
    t30 = t0 + np.arange(len(acc30)) / GRAPH_FPS
    t100 = np.arange(t30[0], t30[-1], 1 / LIVE_HZ)
    poses = []
    try:
        for i in range(0, len(t100), 10):  # 10-sample batches per sensor, as the gateway streams them
            t = t100[i:i + 10]
            for k, key in enumerate(sensors):
                live = np.c_[[np.interp(t, t30, acc30[:, k, c]) for c in range(3)]].T
                worker.add_samples(key, t, live)
            deadline = time.monotonic() + 2.0
            while worker.stats.frames_in < int((t[-1] - t0) * GRAPH_FPS) - 1 and time.monotonic() < deadline:
                time.sleep(0.002)
            pose = worker.latest_pose()
            if pose is not None and (not poses or pose.t_s != poses[-1].t_s):
                poses.append(pose)
    finally:
        worker.stop()
        worker.join(timeout=2)
    assert worker.stats.error == ""
    assert worker.stats.lag_s == 0.5
    assert len(poses) > 20
    errors = []
    for pose in poses:
        frame = int(round((pose.t_s - t0) * GRAPH_FPS))
        assert 0 <= frame < len(truth)
        assert pose.emitted_at_s - pose.t_s == pytest.approx(0.5)
        assert pose.positions_m.shape == truth[frame].shape
        errors.append(np.abs(pose.positions_m[:, 1] - truth[frame][:, 1]).mean())
    assert np.median(errors) < 0.03, np.median(errors)  # metres: the clip's own poses are found


def test_lag_change_and_reset_rebuild_the_synthesizer(graph_and_clip):
    graph, skeleton, acc30, _ = graph_and_clip
    sensors = [("st0", k) for k in range(graph.n_sensors)]
    made = []

    def make(lag):
        made.append(lag)
        return synthesis_setup(graph, skeleton, sensors).make_synthesizer(lag)

    worker = SynthesisWorker(make, sensors, GRAPH_FPS, 0.3)
    worker.start()
    try:
        worker.set_lag(1.0)
        worker.reset()
        deadline = time.monotonic() + 2.0
        while len(made) < 3 and time.monotonic() < deadline:
            worker.add_samples(sensors[0], np.array([0.0]), np.zeros((1, 3)))
            time.sleep(0.01)
    finally:
        worker.stop()
        worker.join(timeout=2)
    # initial build, one for the lag change, one for the reset (order between the last two is a race)
    assert made[0] == 0.3 and len(made) >= 3 and 1.0 in made
    assert worker.stats.lag_s == 1.0
