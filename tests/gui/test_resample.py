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
    res.add("b", np.array([0.0, 0.1]), np.ones((2, 3)))
    res.add("b", np.array([0.1]), np.full((1, 3), 99.0))  # duplicate time: dropped
    t, v, _ = res.frames()
    np.testing.assert_allclose(t, [0.0, 0.1])
    np.testing.assert_allclose(v[:, 1], 1.0)
    res.add("ignored", np.array([5.0]), np.zeros((1, 3)))


def test_a_silent_sensor_does_not_freeze_frames_and_its_gap_is_marked_invalid():
    """b stops at 1.0 s and resumes at 2.0 s while a streams on: frames keep coming (a is live), frames whose
    bracketing b samples are 1 s apart are invalid, frames on either side are valid and exact."""
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
    gap = (t > 1.0 + 1e-9) & (t < 2.0 - 1e-9)
    assert not ok[gap].any() and ok[~gap].all()
    np.testing.assert_allclose(v[ok][:, :, 0], np.c_[t[ok], t[ok]], atol=1e-9)
    assert res.frames_invalid == gap.sum()
