"""Resampling jittery, batched per-sensor streams onto the graph clock reproduces the underlying signal."""
from __future__ import annotations

import numpy as np

from gui.resample import FrameResampler


def signal(t: np.ndarray, k: int) -> np.ndarray:
    """Piecewise-linear-friendly ground truth: linear in t, so interpolation is exact."""
    return np.c_[2.0 * t + k, -t, np.full(len(t), float(k))]


def test_frames_are_exact_on_linear_signals_despite_jitter_and_batching():
    rng = np.random.default_rng(3)
    sensors = ["a", "b", "c"]
    res = FrameResampler(sensors, rate_hz=30.0)
    streams = {}
    for k, s in enumerate(sensors):
        t = np.cumsum(rng.uniform(0.007, 0.013, 400)) + 0.05 * k  # ~100 Hz, jittered, staggered starts
        streams[s] = t
    out_t, out_v = [], []
    for i in range(0, 400, 7):  # interleaved batches of 7 samples
        for k, s in enumerate(sensors):
            t = streams[s][i:i + 7]
            res.add(s, t, signal(t, k))
        ft, fv, ok = res.frames()
        assert ok.all()
        out_t.append(ft)
        out_v.append(fv)
    t = np.concatenate(out_t)
    v = np.concatenate(out_v)
    np.testing.assert_allclose(np.diff(t), 1 / 30.0, atol=1e-9)
    assert t[0] >= max(s[0] for s in streams.values()) - 1e-12
    assert t[-1] <= min(s[-1] for s in streams.values()) + 1e-12
    for k in range(3):
        np.testing.assert_allclose(v[:, k], signal(t, k), atol=1e-9)
    assert res.frames_out == len(t)


def test_no_frame_until_every_sensor_has_data_and_duplicates_ignored():
    res = FrameResampler(["a", "b"], rate_hz=10.0)
    res.add("a", np.array([0.0, 0.1, 0.2]), np.zeros((3, 3)))
    assert len(res.frames()[0]) == 0
    res.add("b", np.array([0.0, 0.1, 0.2]), np.ones((3, 3)))
    res.add("b", np.array([0.1]), np.full((1, 3), 99.0))  # duplicate time: dropped
    t, v, ok = res.frames()
    np.testing.assert_allclose(t, [0.1])  # windows are +-0.05 s: 0.0 starts too early, 0.2 ends too late
    np.testing.assert_allclose(v[:, 1], 1.0)
    assert ok.all()
    res.add("ignored", np.array([5.0]), np.zeros((1, 3)))


def test_a_silent_sensor_does_not_freeze_frames_and_its_gap_is_marked_invalid():
    """b stops at 1.0 s and resumes at 2.0 s while a streams on: frames keep coming (a is live), frames whose
    window touches b's silence are invalid, frames on either side are valid and exact."""
    res = FrameResampler(["a", "b"], rate_hz=10.0, max_gap_s=0.25)
    ta = np.arange(0, 301) / 100.0
    tb = np.r_[np.arange(0, 101), np.arange(200, 301)] / 100.0
    got_t, got_ok, got_v = [], [], []
    for t_end in np.arange(0.1, 3.01, 0.1):  # deliver in 100 ms slices, like the gateway does
        for name, t in (("a", ta), ("b", tb)):
            sl = t[(t > t_end - 0.1 + 1e-9) & (t <= t_end + 1e-9)]
            res.add(name, sl, np.c_[sl, sl, sl])
        ft, fv, ok = res.frames()
        got_t.append(ft)
        got_ok.append(ok)
        got_v.append(fv)
        if 1.5 <= t_end < 2.0:
            assert len(np.concatenate(got_t)) and np.concatenate(got_t)[-1] > 1.2  # not frozen at b's 1.0 s
    t, ok, v = np.concatenate(got_t), np.concatenate(got_ok), np.concatenate(got_v)
    np.testing.assert_allclose(np.diff(t), 0.1, atol=1e-9)
    gap = (t > 0.95 + 1e-9) & (t < 2.05 - 1e-9)  # frames whose +-0.05 s window touches b's silence
    assert not ok[gap].any() and ok[~gap].all()
    np.testing.assert_allclose(v[ok][:, :, 0], np.c_[t[ok], t[ok]], atol=1e-9)
    assert res.frames_invalid == gap.sum()


def test_box_filter_suppresses_aliasing_that_point_sampling_lets_through():
    """A 40 Hz tone sampled at 100 Hz, taken to 30 Hz: point sampling folds it to 10 Hz at nearly full amplitude;
    the resampler's box average keeps less than a quarter of it."""
    fs, tone = 100.0, 40.0
    t = np.arange(0, 10, 1 / fs)
    x = np.sin(2 * np.pi * tone * t + 0.3)
    res = FrameResampler(["a"], rate_hz=30.0)
    res.add("a", t, np.c_[x, x, x])
    ft, fv, ok = res.frames()
    assert ok.all() and len(ft) > 250
    point = np.interp(ft, t, x)
    assert point.std() > 0.5 * x.std()
    assert fv[:, 0, 0].std() < 0.25 * x.std()


def test_box_mean_is_exact_on_lines_and_matches_brute_force():
    from gui.resample import box_mean

    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0, 1, 40))
    v = np.c_[3 * t - 1, np.sin(5 * t)]
    lo = np.array([0.2, 0.5, 0.7])
    hi = lo + 0.05
    got = box_mean(t, v, lo, hi)
    np.testing.assert_allclose(got[:, 0], 3 * (lo + hi) / 2 - 1, atol=1e-12)  # a line: the window centre value
    fine = np.linspace(lo, hi, 20001)  # brute force on the interpolant
    brute = np.array([np.interp(fine[:, k], t, v[:, 1]).mean() for k in range(3)])
    np.testing.assert_allclose(got[:, 1], brute, atol=1e-5)
    np.testing.assert_allclose(box_mean(t, v, lo, lo)[:, 1], np.interp(lo, t, v[:, 1]))  # zero width: the point
