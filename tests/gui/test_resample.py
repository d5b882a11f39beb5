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
        ft, fv = res.frames()
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
    t, v = res.frames()
    np.testing.assert_allclose(t, [0.0, 0.1])
    np.testing.assert_allclose(v[:, 1], 1.0)
    res.add("ignored", np.array([5.0]), np.zeros((1, 3)))
