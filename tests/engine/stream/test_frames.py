"""Resampling jittery, batched per-sensor streams onto the frame clock: exact on known signals, dropouts marked
and never interpolated across, and the frames bit-identical however the samples were batched."""
from __future__ import annotations

import numpy as np
import pytest

from engine.stream import FrameBatch, FrameResampler, box_mean, resample_uniform


def signal(t: np.ndarray, k: int) -> np.ndarray:
    """Piecewise-linear-friendly ground truth: linear in t, so interpolation is exact."""
    return np.c_[2.0 * t + k, -t, np.full(len(t), float(k))]


def jittered_streams(seed: int = 3, n: int = 400) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {s: np.cumsum(rng.uniform(0.007, 0.013, n)) + 0.05 * k + 100.0 for k, s in enumerate("abc")}


def feed(res: FrameResampler, streams: dict[str, np.ndarray], batch: int, values=signal) -> FrameBatch:
    out = []
    n = len(next(iter(streams.values())))
    for i in range(0, n, batch):
        for k, (s, t) in enumerate(streams.items()):
            res.add(s, t[i:i + batch], values(t[i:i + batch], k))
        out.append(res.frames())
    return FrameBatch.concatenate(out, len(streams))


def test_frames_are_exact_on_linear_signals_despite_jitter_and_batching():
    streams = jittered_streams()
    res = FrameResampler(list(streams), rate_hz=30.0)
    got = feed(res, streams, 7)
    assert got.valid.all()
    assert np.array_equal(np.diff(got.index), np.ones(len(got) - 1))
    assert np.array_equal(got.t_s, got.index / 30.0)  # the absolute clock, not an accumulated float
    assert got.t_s[0] - 1 / 60 >= max(s[0] for s in streams.values()) - 1e-12
    assert got.t_s[-1] + 1 / 60 <= min(s[-1] for s in streams.values()) + 1e-12
    for k in range(3):
        np.testing.assert_allclose(got.acc_g[:, k], signal(got.t_s, k), atol=1e-9)
    assert res.frames_out == len(got)


@pytest.mark.parametrize("batch", [1, 3, 10, 400])
def test_frames_do_not_depend_on_batching_to_the_bit(batch):
    """Live (small batches, history trimmed as it goes) and offline (everything at once) must agree exactly:
    each window's integral is summed from the window's own samples."""
    streams = jittered_streams(seed=5)
    wiggle = lambda t, k: np.c_[np.sin(7 * t + k), np.cos(3 * t) ** 2, t * t]  # noqa: E731
    reference = feed(FrameResampler(list(streams), 30.0), streams, 400, wiggle)
    got = feed(FrameResampler(list(streams), 30.0, history_s=0.0), streams, batch, wiggle)
    common = np.intersect1d(reference.index, got.index)
    assert len(common) > 100
    a = reference.acc_g[np.isin(reference.index, common)]
    b = got.acc_g[np.isin(got.index, common)]
    assert np.array_equal(a, b)


def test_no_frame_until_every_sensor_has_data_and_duplicates_ignored():
    res = FrameResampler(["a", "b"], rate_hz=10.0)
    res.add("a", np.array([0.0, 0.1, 0.2]), np.zeros((3, 3)))
    assert len(res.frames()) == 0
    res.add("b", np.array([0.0, 0.1, 0.2]), np.ones((3, 3)))
    res.add("b", np.array([0.1]), np.full((1, 3), 99.0))  # duplicate time: dropped
    got = res.frames()
    np.testing.assert_allclose(got.t_s, [0.1])  # windows are +-0.05 s: 0.0 starts too early, 0.2 ends too late
    np.testing.assert_allclose(got.acc_g[:, 1], 1.0)
    assert got.valid.all()
    res.add("ignored", np.array([5.0]), np.zeros((1, 3)))


def test_a_silent_sensor_does_not_freeze_frames_and_its_gap_is_marked_invalid():
    """b stops at 1.0 s and resumes at 2.0 s while a streams on: after waiting ``wait_s`` for b, frames keep coming
    (a is live), frames whose window touches b's silence are invalid with NaN accelerations, frames on either
    side are valid and exact — and offline (all samples at once) marks exactly the same frames."""
    ta = np.arange(0, 301) / 100.0
    tb = np.r_[np.arange(0, 101), np.arange(200, 301)] / 100.0
    res = FrameResampler(["a", "b"], rate_hz=10.0, max_gap_s=0.25, wait_s=0.5)
    got = []
    for t_end in np.arange(0.1, 3.01, 0.1):  # deliver in 100 ms slices, like the gateway does
        for name, t in (("a", ta), ("b", tb)):
            sl = t[(t > t_end - 0.1 + 1e-9) & (t <= t_end + 1e-9)]
            res.add(name, sl, np.c_[sl, sl, sl])
        got.append(res.frames())
        if 1.4 < t_end < 1.5:
            assert FrameBatch.concatenate(got, 2).t_s[-1] < 1.0  # still waiting for b (0.5 s)
        if 1.6 <= t_end < 2.0:
            assert FrameBatch.concatenate(got, 2).t_s[-1] > 1.2  # then not frozen at b's 1.0 s
    live = FrameBatch.concatenate(got, 2)
    gap = (live.t_s > 0.95 + 1e-9) & (live.t_s < 2.05 - 1e-9)  # frames whose +-0.05 s window touches the silence
    assert not live.valid[gap].any() and live.valid[~gap].all()
    assert np.isnan(live.acc_g[gap]).all()  # nothing made up across the dropout
    np.testing.assert_allclose(live.acc_g[live.valid][:, :, 0], np.c_[live.t_s[live.valid], live.t_s[live.valid]],
                               atol=1e-9)
    assert res.frames_invalid == gap.sum()
    offline = FrameResampler(["a", "b"], rate_hz=10.0, max_gap_s=0.25)
    offline.add("a", ta, np.c_[ta, ta, ta])
    offline.add("b", tb, np.c_[tb, tb, tb])
    off = offline.frames()
    common = np.isin(off.index, live.index)
    assert np.array_equal(off.valid[common], live.valid)


def test_a_late_sensor_is_waited_for_so_live_frames_equal_offline():
    """b's samples arrive 0.8 s after a's (a loaded gateway): within wait_s nothing is marked invalid."""
    t = np.arange(0, 300) / 100.0
    res = FrameResampler(["a", "b"], rate_hz=30.0)  # wait 1 s
    got = []
    for t_end in np.arange(0.1, 3.91, 0.1):
        for name, lag in (("a", 0.0), ("b", 0.8)):
            sl = t[(t > t_end - 0.1 - lag + 1e-9) & (t <= t_end - lag + 1e-9)]
            res.add(name, sl, np.c_[sl, sl, sl])
        got.append(res.frames())
    live = FrameBatch.concatenate(got, 2)
    assert live.valid.all() and len(live) > 80
    with pytest.raises(ValueError, match="wait_s"):
        FrameResampler(["a"], 30.0, max_gap_s=0.5, wait_s=0.25)


def test_start_at_rewinds_within_history_and_until_holds_frames_back():
    t = np.arange(0, 300) / 100.0
    res = FrameResampler(["a"], rate_hz=10.0)
    res.add("a", t, np.c_[t, t, t])
    assert res.frames(until_s=1.0).t_s[-1] == pytest.approx(1.0)
    first = res.frames()
    assert first.index[0] == 11
    res.start_at(1.96)  # back in time, within the 2 s history
    again = res.frames()
    assert again.index[0] == 20 and np.allclose(again.acc_g[:, 0, 0], np.arange(20, 30) / 10.0)


def test_a_start_long_before_any_data_begins_where_the_data_does():
    """A console that joins a take 40 s after it started is told the take's start: it must not push 1 200 empty
    frames (an hour-old take: 108 000) through the engine before the first real one; a start within the
    history (a late recording notice) still rewinds exactly as offline."""
    streams = jittered_streams()  # every sensor starts at about 100 s
    res = FrameResampler(list(streams), rate_hz=30.0)
    res.start_at(60.0)
    got = feed(res, streams, 10)
    assert got.valid.all() and got.index[0] == int(np.ceil(max(s[0] for s in streams.values()) * 30 + 0.5))
    near = FrameResampler(list(streams), rate_hz=30.0)
    near.start_at(99.0)  # within history_s of the data: the frames before it are dropouts, as offline
    early = feed(near, streams, 10)
    assert early.index[0] == 99 * 30 and not early.valid[:30].any() and early.valid[-100:].all()


def test_box_filter_suppresses_aliasing_that_point_sampling_lets_through():
    """A 40 Hz tone sampled at 100 Hz, taken to 30 Hz: point sampling folds it to 10 Hz at nearly full amplitude;
    the resampler's box average keeps less than a quarter of it."""
    fs, tone = 100.0, 40.0
    t = np.arange(0, 10, 1 / fs)
    x = np.sin(2 * np.pi * tone * t + 0.3)
    got = resample_uniform(np.repeat(x[:, None, None], 3, axis=2), fs, 30.0)
    assert got.valid.all() and len(got) > 250
    point = np.interp(got.t_s, t, x)
    assert point.std() > 0.5 * x.std()
    assert got.acc_g[:, 0, 0].std() < 0.25 * x.std()


def test_resample_uniform_marks_nan_rows_as_dropouts():
    x = np.ones((300, 2, 3))
    x[100:150, 1] = np.nan  # 0.5 s silence on sensor 1
    got = resample_uniform(x, 100.0, 30.0)
    bad = (got.t_s > 0.99 - 1 / 60) & (got.t_s < 1.50 + 1 / 60)
    assert not got.valid[bad].any() and got.valid[~bad].all()
    assert np.array_equal(got.acc_g[got.valid], np.ones((got.valid.sum(), 2, 3)))


def test_box_mean_is_exact_on_lines_and_matches_brute_force():
    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0, 1, 40))
    v = np.c_[3 * t - 1, np.sin(5 * t)]
    lo = np.array([0.2, 0.5, 0.7, t[10]])
    hi = np.r_[lo[:3] + 0.05, t[13]]  # the last window starts and ends exactly on samples
    got = box_mean(t, v, lo, hi)
    np.testing.assert_allclose(got[:, 0], 3 * (lo + hi) / 2 - 1, atol=1e-12)  # a line: the window centre value
    fine = np.linspace(lo, hi, 20001)  # brute force on the interpolant
    brute = np.array([np.interp(fine[:, k], t, v[:, 1]).mean() for k in range(4)])
    np.testing.assert_allclose(got[:, 1], brute, atol=1e-5)


def test_a_clock_that_steps_back_drops_the_same_samples_however_the_stream_is_batched():
    """A recorded stream whose times step back (the online clock map re-fitted): samples not after every earlier
    one are dropped by a running maximum, so live batches and one offline pass keep the same samples."""
    t = np.arange(0, 300) / 100.0
    t[150:160] -= 0.2  # ten samples stamped 0.2 s early
    v = np.c_[t, t, t]
    offline = FrameResampler(["a"], 30.0)
    offline.add("a", t, v)
    ref = offline.frames()
    for batch in (1, 7, 25):
        live = FrameResampler(["a"], 30.0)
        got = []
        for i in range(0, len(t), batch):
            live.add("a", t[i:i + batch], v[i:i + batch])
            got.append(live.frames())
        got = FrameBatch.concatenate(got, 1)
        common = np.isin(ref.index, got.index)
        assert common.sum() > 80 and np.array_equal(ref.acc_g[common], got.acc_g[np.isin(got.index, ref.index)])
    assert ref.valid.all()  # the 0.1 s of dropped samples is a gap shorter than max_gap_s


def _turning(t: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """A sensor turning about a fixed axis at a constant rate (k-dependent), with its sign flipped on every other
    sample as a device may send it (q and -q are one rotation): (quaternions (N, 4), rate (N, 3) rad/s)."""
    axis = np.array([1.0, 2.0, 2.0 + k]) / np.linalg.norm([1.0, 2.0, 2.0 + k])
    rate = 1.5 + 0.5 * k
    half = 0.5 * rate * t
    q = np.c_[np.cos(half), np.sin(half)[:, None] * axis]
    q[::2] *= -1
    return q, np.tile(axis * rate, (len(t), 1))


def test_orientation_and_rate_frames_are_the_window_means_and_survive_sign_flips():
    """Constant rate: the box mean of the rate is the rate; the normalised, sign-aligned mean of a quaternion
    turning uniformly across a frame window is the rotation at the window's centre (by symmetry), to the
    accuracy of piecewise-linear interpolation between 100 Hz samples."""
    streams = jittered_streams()
    res = FrameResampler(list(streams), rate_hz=30.0)
    out = []
    for i in range(0, 400, 9):
        for k, (s, t) in enumerate(streams.items()):
            q, g = _turning(t[i:i + 9], k)
            res.add(s, t[i:i + 9], signal(t[i:i + 9], k), q, g)
        out.append(res.frames())
    got = FrameBatch.concatenate(out, 3)
    assert got.valid.all() and got.quat_wxyz.shape == (len(got), 3, 4) and len(got) > 100
    for k in range(3):
        want_q, want_g = _turning(got.t_s, k)
        dots = np.abs(np.einsum("fi,fi->f", got.quat_wxyz[:, k], want_q))
        assert np.degrees(2 * np.arccos(np.minimum(dots, 1.0))).max() < 0.05
        np.testing.assert_allclose(got.gyro_rps[:, k], want_g, atol=1e-12)
        assert (got.quat_wxyz[:, k, 0] >= 0).all()
        np.testing.assert_allclose(np.linalg.norm(got.quat_wxyz[:, k], axis=1), 1.0, atol=1e-12)


@pytest.mark.parametrize("batch", [1, 4, 400])
def test_orientation_frames_do_not_depend_on_batching_or_where_the_stream_started(batch):
    """The sign chain differs with the first sample a resampler saw (live joins late, offline sees all), but
    only by a whole-window sign that the canonical sign removes: bit-identical frames."""
    streams = jittered_streams(seed=8)

    def run(res: FrameResampler, first: int, step: int) -> FrameBatch:
        out = []
        for i in range(first, 400, step):
            for k, (s, t) in enumerate(streams.items()):
                q, g = _turning(t[i:i + step] * 3.0, k)
                res.add(s, t[i:i + step], signal(t[i:i + step], k), q, g)
            out.append(res.frames())
        return FrameBatch.concatenate(out, 3)

    reference = run(FrameResampler(list(streams), 30.0), 0, 400)
    got = run(FrameResampler(list(streams), 30.0, history_s=0.0), 37, batch)
    common = np.intersect1d(reference.index, got.index)
    assert len(common) > 80
    for name in ("acc_g", "quat_wxyz", "gyro_rps"):
        assert np.array_equal(getattr(reference, name)[np.isin(reference.index, common)],
                              getattr(got, name)[np.isin(got.index, common)]), name


def test_missing_quaternions_and_accelerometer_only_streams():
    """A NaN quaternion blanks only that sensor's orientation in the frames it touches; a resampler fed no
    orientation gives None, and a mixed one NaN for the sensors without."""
    t = np.arange(0.0, 2.0, 0.01)
    q, g = _turning(t, 0)
    q[100:103] = np.nan
    res = FrameResampler(["a", "b"], 30.0)
    res.add("a", t, signal(t, 0), q, g)
    res.add("b", t, signal(t, 1))
    got = res.frames()
    hole = (got.t_s > t[99] - 1 / 60) & (got.t_s < t[103] + 1 / 60)
    assert got.valid.all() and hole.sum() >= 1
    assert np.isnan(got.quat_wxyz[hole, 0]).all() and not np.isnan(got.quat_wxyz[~hole, 0]).any()
    assert np.isnan(got.quat_wxyz[:, 1]).all() and np.isnan(got.gyro_rps[:, 1]).all()
    assert not np.isnan(got.gyro_rps[:, 0]).any()
    only_acc = FrameResampler(["a"], 30.0)
    only_acc.add("a", t, signal(t, 0))
    frames = only_acc.frames()
    assert frames.quat_wxyz is None and frames.gyro_rps is None and len(frames) > 50


def test_resample_uniform_carries_orientation_and_rate():
    t = np.arange(120) / 60.0
    q, g = _turning(t, 1)
    acc = np.stack([signal(t, 0)], axis=1)
    got = resample_uniform(acc, 60.0, 30.0, quat_wxyz=q[:, None], gyro_rps=g[:, None])
    assert got.quat_wxyz.shape == (len(got), 1, 4) and len(got) == 60
    want, _ = _turning(got.t_s, 1)
    dots = np.abs(np.einsum("fi,fi->f", got.quat_wxyz[:, 0], want))
    assert np.degrees(2 * np.arccos(np.minimum(dots, 1.0)))[1:-1].max() < 0.1
