"""`StreamSynthesis` pushes the same frames to its engine live (batch by batch, late camera, late sensor, a
recording notice that arrives after the take's first frame) as offline in one pass."""
from __future__ import annotations

import numpy as np
import pytest

from engine.stream import RecordedStreams, StreamSynthesis, synthesize_streams, take_start_s
from engine.stream.engines import EnginePose


class InputLog:
    """An engine that decides nothing but keeps exactly what it was pushed (the path's output)."""

    def __init__(self) -> None:
        self.pushed: list[tuple] = []

    def push(self, acc_g, pos_m=None, heading_rad=None, *, quat_wxyz=None, gyro_rps=None):
        self.pushed.append((None if acc_g is None else acc_g.copy(), None if pos_m is None else pos_m.copy(),
                            heading_rad))
        return [EnginePose(len(self.pushed) - 1, np.zeros((1, 3)))]

    def flush(self):
        return []


def recorded(seconds: float = 6.0) -> RecordedStreams:
    rng = np.random.default_rng(2)
    samples = {}
    for k in range(3):
        t = 50.0 + np.cumsum(rng.uniform(0.008, 0.012, int(seconds * 100)))
        if k == 1:
            t = t[(t < 52.0) | (t > 52.6)]  # a 0.6 s dropout
        samples[k] = (t, np.c_[np.sin(4 * t + k), np.cos(t), t - 50.0])
    tc = np.arange(50.0, 50.0 + seconds, 1 / 12)
    camera = [(float(x), None if 53.0 < x < 53.3 else [x - 50.0, -2.0], None) for x in tc]
    return RecordedStreams(samples, camera, 50.4)


def stream_live(live: StreamSynthesis, rec: RecordedStreams, until_s: float) -> None:
    """Feed a recorded take to a live session in 0.1 s slices of every stream (every channel it has), stepping
    after each, as the console's worker does."""
    for t_end in np.arange(50.1, until_s, 0.1):
        for k, (t, *values) in rec.samples.items():
            sl = (t > t_end - 0.1) & (t <= t_end)
            live.add_samples(k, t[sl], *(v[sl] for v in values))
        for fix in [c for c in rec.camera if t_end - 0.1 < c[0] <= t_end]:
            live.add_camera(*fix)
        live.step()


def live_and_offline(engine: type, live_rec: RecordedStreams, offline_rec: RecordedStreams, until_s: float):
    """A live session fed ``live_rec`` in slices from the take's defined first frame, and the offline synthesis
    of ``offline_rec``: (live session, offline session, live engine, offline engine)."""
    engines = []
    make = lambda: engines.append(engine()) or engines[-1]  # noqa: E731
    live = StreamSynthesis(make, [0, 1, 2], 30.0, start_s=take_start_s(live_rec.started_t_host_s))
    stream_live(live, live_rec, until_s)
    live_engine = engines[-1]
    _, offline = synthesize_streams(make, offline_rec, [0, 1, 2], 30.0)
    return live, offline, live_engine, engines[-1]


@pytest.mark.parametrize("sensor_lag_s, camera_lag_s", [(0.9, 0.0), (0.0, 1.5)])
def test_live_pushes_equal_offline_despite_late_camera_late_sensor_and_late_notice(sensor_lag_s, camera_lag_s):
    """Sensor 2 late by less than wait_s (1 s), or the camera by less than camera_wait_s (2 s): waited for."""
    rec = recorded()
    logs = []
    make = lambda: logs.append(InputLog()) or logs[-1]  # noqa: E731
    live = StreamSynthesis(make, [0, 1, 2], 30.0)
    cam = list(rec.camera)
    for t_end in np.arange(50.1, 57.6, 0.1):
        for k, (t, a) in rec.samples.items():
            lag = sensor_lag_s if k == 2 else 0.0
            sl = (t > t_end - 0.1 - lag) & (t <= t_end - lag)
            live.add_samples(k, t[sl], a[sl])
        for fix in [c for c in cam if t_end - 0.1 - camera_lag_s < c[0] <= t_end - camera_lag_s]:
            live.add_camera(*fix)
        if abs(t_end - 51.5) < 0.05:  # the recording notice, after frames past the take's first were pushed
            live.restart(take_start_s(rec.started_t_host_s))
        live.step()
    live_log = logs[-1].pushed
    assert live.first_frame == int(np.ceil(take_start_s(50.4) * 30.0 - 1e-9))
    _, offline = synthesize_streams(make, rec, [0, 1, 2], 30.0)
    offline_log = logs[-1].pushed
    assert live.stats.reproducible and live.stats.late_samples == live.stats.late_fixes == 0
    assert offline.first_frame == live.first_frame and len(live_log) > 100
    for (a1, p1, _), (a2, p2, _) in zip(live_log, offline_log):
        assert (a1 is None) == (a2 is None) and (p1 is None) == (p2 is None)
        assert a1 is None or np.array_equal(a1, a2)
        assert p1 is None or np.array_equal(p1, p2)
    assert sum(a is None for a, _, _ in live_log) > 10  # the dropout was stepped without accelerations
    assert sum(p is None for _, p, _ in live_log) > 5   # and the lost player without a position


@pytest.mark.parametrize("sensor_lag_s, camera_lag_s", [(1.5, 0.0), (0.0, 3.0)])
def test_data_later_than_the_waits_is_counted_and_the_session_says_it_is_not_reproducible(sensor_lag_s,
                                                                                        camera_lag_s):
    rec = recorded()
    live = StreamSynthesis(InputLog, [0, 1, 2], 30.0)
    for t_end in np.arange(50.1, 57.6, 0.1):
        for k, (t, a) in rec.samples.items():
            lag = sensor_lag_s if k == 2 else 0.0
            sl = (t > t_end - 0.1 - lag) & (t <= t_end - lag)
            live.add_samples(k, t[sl], a[sl])
        for fix in [c for c in rec.camera if t_end - 0.1 - camera_lag_s < c[0] <= t_end - camera_lag_s]:
            live.add_camera(*fix)
        live.step()
    assert not live.stats.reproducible
    assert (live.stats.late_samples > 0) == (sensor_lag_s > 0) and (live.stats.late_fixes > 0) == (camera_lag_s > 0)


def test_a_take_whose_camera_track_ends_before_its_samples_ends_there_as_live_did():
    """The recorder stops before the fixes of the last camera latency are published: the take's camera track ends
    0.4 s before its samples. Offline must not push those last frames without a position, which live pushed with
    fixes the take does not have."""
    full = recorded()
    stop = 55.0
    take = RecordedStreams({k: (t[t <= stop], a[t <= stop]) for k, (t, a) in full.samples.items()},
                           [c for c in full.camera if c[0] <= stop - 0.4], full.started_t_host_s)
    _, offline, live_engine, offline_engine = live_and_offline(InputLog, full, take, 56.1)
    live_log, offline_log = live_engine.pushed, offline_engine.pushed
    assert offline.camera.newest_s <= stop - 0.4 and len(offline_log) < len(live_log)
    assert (len(offline_log) + offline.first_frame) / 30.0 <= stop - 0.4 + 1 / 30
    for (a1, p1, _), (a2, p2, _) in zip(live_log, offline_log):
        assert np.array_equal(a1, a2) and (p1 is None) == (p2 is None) and (p1 is None or np.array_equal(p1, p2))


def test_frames_pushed_in_slices_are_the_offline_frames_and_the_backlog_is_measured():
    """A live caller whose engine is slower than real time pushes at most ``max_frames`` per step, so it can serve
    its inputs and report how far it trails the stream (`behind_s`) between slices; the frames are unchanged."""
    rec = recorded()
    logs = []
    make = lambda: logs.append(InputLog()) or logs[-1]  # noqa: E731
    live = StreamSynthesis(make, [0, 1, 2], 30.0, start_s=take_start_s(rec.started_t_host_s))
    for k, (t, a) in rec.samples.items():
        live.add_samples(k, t, a)
    for fix in rec.camera:
        live.add_camera(*fix)
    assert live.behind_s == 0.0  # nothing pushed yet
    live.step(max_frames=10)
    newest = max(t[-1] for t, _ in rec.samples.values())
    first_t = live.first_frame / 30.0
    assert len(logs[-1].pushed) == 10
    assert live.behind_s == pytest.approx(newest - (first_t + 9 / 30.0))  # ~5 s of stream still to push
    while live.step(max_frames=10):
        pass
    sliced = logs[-1].pushed
    assert live.behind_s < 0.5  # caught up: only the frames the camera / the window ends hold back
    _, offline = synthesize_streams(make, rec, [0, 1, 2], 30.0)
    assert offline.first_frame == live.first_frame and len(sliced) == len(logs[-1].pushed) > 100
    for (a1, p1, _), (a2, p2, _) in zip(sliced, logs[-1].pushed):
        assert (a1 is None) == (a2 is None) and (a1 is None or np.array_equal(a1, a2))
        assert (p1 is None) == (p2 is None) and (p1 is None or np.array_equal(p1, p2))


class ChannelLog(InputLog):
    """An engine that takes orientation and angular rate (the issue-18 protocol) and keeps them."""

    def __init__(self) -> None:
        super().__init__()
        self.channels: list[tuple] = []

    def push(self, acc_g, pos_m=None, heading_rad=None, *, quat_wxyz=None, gyro_rps=None):
        self.channels.append((None if quat_wxyz is None else quat_wxyz.copy(),
                              None if gyro_rps is None else gyro_rps.copy()))
        return super().push(acc_g, pos_m, heading_rad)


def with_orientation(rec: RecordedStreams) -> RecordedStreams:
    """The same take with every sensor also streaming a turning orientation (sign flips as devices send them)
    and its angular rate."""
    samples = {}
    for k, (t, acc) in rec.samples.items():
        half = 0.5 * (1.0 + k) * t
        quat = np.c_[np.cos(half), np.sin(half), np.zeros((len(t), 2))] * np.where(np.arange(len(t)) % 3, 1, -1)[:, None]
        samples[k] = (t, acc, quat, np.tile([1.0 + k, 0.0, 0.0], (len(t), 1)))
    return RecordedStreams(samples, rec.camera, rec.started_t_host_s)


def test_live_orientations_equal_offline_bit_for_bit():
    rec = with_orientation(recorded())
    live, offline, live_engine, offline_engine = live_and_offline(ChannelLog, rec, rec, 57.6)
    live_log, offline_log = live_engine.channels, offline_engine.channels
    assert live.stats.reproducible and len(live_log) > 100
    assert offline.stats.frames_with_orientation == offline.stats.frames_with_gyro > 100
    n = min(len(live_log), len(offline_log))
    for (q1, g1), (q2, g2) in zip(live_log[:n], offline_log[:n]):
        assert (q1 is None) == (q2 is None)   # None: the dropout frames, as for the accelerations
        assert q1 is None or (np.array_equal(q1, q2) and np.array_equal(g1, g2))
    assert sum(q is None for q, _ in live_log) > 10
    valid = [q for q, _ in live_log if q is not None]
    np.testing.assert_allclose(np.linalg.norm(valid, axis=-1), 1.0, atol=1e-12)
