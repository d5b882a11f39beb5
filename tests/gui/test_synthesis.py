"""Live synthesis in the console's worker thread, and in the child process the console runs it in: live-rate
batches in, the engine's poses out — and exactly the poses offline synthesis of the same recorded streams gives.

Ground truth: a shipped clip that is in the graph, streamed noise-free as virtual accelerometers at 100 Hz.
The fixed-lag Viterbi must then recover that clip's own poses, so joint heights match the clip's FK."""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
import pytest

from engine.mocap import SEED000_SENSORS, forward_kinematics, load_clip, sample_clips, standard_placements, virtual_accelerometers
from engine.stream import RecordedStreams, synthesize_streams, take_start_s
from engine.graph.online_engine import load_or_build_graph, motion_graph_spec
from engine.stream.databases import GRAPH_FPS
from gui.engine_link import synthesis_setup
from gui.synthesis import SynthesisWorker
from gui.synthesis_process import SynthesisProcess

LIVE_HZ = 100.0


@pytest.fixture(scope="module")
def graph_and_clip(tmp_path_factory):
    graph, skeleton, _ = load_or_build_graph(cache_dir=tmp_path_factory.mktemp("graphs"))
    motion = load_clip(sample_clips()["16_11"], fps=GRAPH_FPS)
    acc = virtual_accelerometers(motion, standard_placements(motion.skeleton, SEED000_SENSORS))
    truth, _ = forward_kinematics(motion)
    return motion_graph_spec(graph, "shipped clips", skeleton), acc, truth


@pytest.fixture(params=[SynthesisWorker, SynthesisProcess], ids=["thread", "process"])
def runner(request):
    """The console's two ways to run a synthesizer (same interface, same worker code)."""
    return request.param


def live_streams(acc30: np.ndarray, t0: float, sensors) -> dict:
    """100 Hz jittered sample times over the clip, values interpolated from the 30 Hz virtual readings."""
    t30 = t0 + np.arange(len(acc30)) / GRAPH_FPS
    rng = np.random.default_rng(7)
    out = {}
    for k, key in enumerate(sensors):
        t = np.arange(t30[0], t30[-1], 1 / LIVE_HZ) + rng.uniform(0, 0.002, int(np.ceil((t30[-1] - t30[0]) * LIVE_HZ)))
        t = np.sort(t[t <= t30[-1]])
        out[key] = (t, np.c_[[np.interp(t, t30, acc30[:, k, c]) for c in range(3)]].T)
    return out


def run_worker(worker: SynthesisWorker, streams: dict, camera: list, batch_s: float = 0.1,
               started_s: float | None = None) -> None:
    """Feed the worker as the bridge does: sample batches per sensor and camera fixes, in 100 ms slices."""
    t_all = np.concatenate([t for t, _ in streams.values()])
    for t_end in np.arange(t_all.min() + batch_s, t_all.max() + batch_s, batch_s):
        for key, (t, acc) in streams.items():
            sl = (t > t_end - batch_s) & (t <= t_end)
            worker.add_samples(key, t[sl], acc[sl])
        for tc, pos, head in camera:
            if t_end - batch_s < tc <= t_end:
                worker.add_camera(tc, pos, head)
        if started_s is not None and t_end >= started_s + 0.9:  # the notice arrives after the take's first frame
            worker.recording_started(started_s)
            started_s = None
    deadline = time.monotonic() + 30
    expected = int((t_all.max() - t_all.min()) * GRAPH_FPS) - 20
    while worker.stats.frames_in < expected and time.monotonic() < deadline:
        time.sleep(0.01)


def test_worker_recovers_clip_poses_from_live_batches(graph_and_clip, runner):
    spec, acc30, truth = graph_and_clip
    sensors = [("st0", k) for k in range(len(spec.sensor_names))]
    worker = runner(synthesis_setup(spec, sensors, lag_s=0.5), keep_poses=True)
    worker.start()
    t0 = 100.0
    try:
        run_worker(worker, live_streams(acc30, t0, sensors), [])
    finally:
        worker.stop()
        worker.join(timeout=5)
    assert worker.stats.error == ""
    start, poses = worker.poses()
    assert len(poses) > 20 and worker.latest_pose().frame == poses[-1].frame
    errors = []
    for pose in poses:
        frame = int(round((pose.t_s - t0) * GRAPH_FPS))
        assert 0 <= frame < len(truth) and pose.t_s == pose.frame / GRAPH_FPS
        errors.append(np.abs(pose.joint_positions_m[:, 1] - truth[frame][:, 1]).mean())
    assert np.median(errors) < 0.03, np.median(errors)  # metres: the clip's own poses are found


def test_live_worker_equals_offline_synthesis_of_the_take_bit_for_bit(graph_and_clip):
    """A take starts mid-stream (the notice reaching the worker 0.9 s late, after frames past the take's first were pushed: the worker rewinds), the camera sees the player at 12 fps
    with a 0.4 s tracking loss and a sensor drops out for 0.4 s. The worker, fed in 100 ms slices, must give exactly
    the poses of one offline pass over the same recorded samples and fixes (same frames, same floats)."""
    spec, acc30, _ = graph_and_clip
    sensors = [("st0", k) for k in range(len(spec.sensor_names))]
    t0 = 200.0
    streams = live_streams(acc30, t0, sensors)
    t, a = streams[sensors[2]]
    drop = (t > t0 + 2.0) & (t < t0 + 2.4)
    streams[sensors[2]] = (t[~drop], a[~drop])
    tc = np.arange(t0, t0 + len(acc30) / GRAPH_FPS, 1 / 12)
    camera = [(float(x), None if 1.5 < x - t0 < 1.9 else [0.3 * (x - t0), -2.0], 0.1) for x in tc]
    started = t0 + 0.8
    # the console's runner: the worker thread inside a child process (the thread alone is checked by the backlog
    # test below and the clip test above)
    worker = SynthesisProcess(replace(synthesis_setup(spec, sensors, lag_s=0.5)), keep_poses=True)
    worker.start()
    try:
        run_worker(worker, streams, camera, started_s=started)
    finally:
        worker.stop()
        worker.join(timeout=5)
    start, live = worker.poses()
    assert worker.stats.error == "" and start == int(np.ceil(take_start_s(started) * GRAPH_FPS - 1e-9))
    assert worker.stats.frames_invalid > 0 and worker.stats.frames_with_camera > 0
    assert worker.stats.late_samples == worker.stats.late_fixes == 0
    # the recorder holds what arrived after the start (and a little before the first frame's window)
    recorded = RecordedStreams({k: (t[t >= started], a[t >= started]) for k, (t, a) in streams.items()},
                               [c for c in camera if c[0] >= started], started)
    offline, session = synthesize_streams(lambda: spec.make(0.5), recorded, sensors, spec.rate_hz)
    assert session.first_frame == start
    by_frame = {p.frame: p for p in offline}
    assert len(live) > 30
    for p in live:
        assert np.array_equal(p.joint_positions_m, by_frame[p.frame].joint_positions_m), p.frame


def test_lag_change_and_reset_rebuild_the_engine(graph_and_clip):
    spec, _, _ = graph_and_clip
    sensors = [("st0", k) for k in range(len(spec.sensor_names))]
    made = []
    counting = replace(spec, make=lambda lag: made.append(lag) or spec.make(lag))
    worker = SynthesisWorker(synthesis_setup(counting, sensors, lag_s=0.3))
    worker.start()
    try:
        worker.set_lag(1.0)
        worker.reset()
        deadline = time.monotonic() + 5.0
        while len(made) < 3 and time.monotonic() < deadline:
            worker.add_samples(sensors[0], np.array([time.monotonic()]), np.zeros((1, 3)))
            time.sleep(0.01)
    finally:
        worker.stop()
        worker.join(timeout=2)
    # initial build, one for the lag change, one for the reset's fresh session (at the new lag)
    assert made == [0.3, 1.0, 1.0]
    assert worker.stats.lag_s == 1.0


def test_a_backlog_given_at_once_is_worked_off_in_slices_with_the_offline_poses(graph_and_clip):
    """Everything at once (a console that was stalled, or an engine slower than real time): the worker pushes at
    most `STEP_S` of frames per pass, so its stats and displayed pose move while it works the backlog off, and
    the poses are still exactly the offline ones."""
    spec, acc30, _ = graph_and_clip
    sensors = [("st0", k) for k in range(len(spec.sensor_names))]
    streams = live_streams(acc30, 300.0, sensors)
    worker = SynthesisWorker(synthesis_setup(spec, sensors, lag_s=0.5), keep_poses=True)
    worker.start()
    try:
        run_worker(worker, streams, [], batch_s=1e3)
    finally:
        worker.stop()
        worker.join(timeout=5)
    _, live = worker.poses()
    assert worker.stats.error == "" and worker.stats.behind_s < 0.1
    offline, _ = synthesize_streams(lambda: spec.make(0.5), RecordedStreams(streams), sensors, spec.rate_hz)
    by_frame = {p.frame: p for p in offline}
    assert len(live) > 100
    for p in live:
        assert np.array_equal(p.joint_positions_m, by_frame[p.frame].joint_positions_m), p.frame


def test_falling_behind_is_reported_with_the_engine_cost_and_the_real_time_budget():
    from gui.synthesis import SynthesisStats

    slow = SynthesisStats(lag_s=0.5, push_ms=100.0, behind_s=27.0)
    assert slow.falling_behind(25.0) == ("FALLING BEHIND: 27.0 s behind the stream; the engine takes 100 ms/frame, "
                                         "real time needs < 40 ms (2.5x slower than real time)")
    assert SynthesisStats(lag_s=0.5, push_ms=2.0, behind_s=1.2).falling_behind(30.0) == ""
