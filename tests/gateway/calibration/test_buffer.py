"""SampleBuffer keeps exactly the samples it should across growth, drops and compaction."""
from __future__ import annotations

import numpy as np

from gateway.calibration.buffer import SampleBuffer


def test_windows_match_a_reference_through_growth_drops_and_compaction():
    rng = np.random.default_rng(0)
    buf = SampleBuffer(capacity=8)
    t_all = np.arange(5000) * 0.01
    acc_all = rng.normal(size=(5000, 3))
    kept_from = 0.0
    for start in range(0, 5000, 7):
        buf.extend(t_all[start : start + 7], acc_all[start : start + 7])
        now = t_all[min(start + 6, 4999)]
        if start % 3 == 0:
            kept_from = max(kept_from, now - 1.5)
            buf.drop_before(kept_from)
        ref = (t_all >= kept_from) & (t_all <= now)
        np.testing.assert_array_equal(buf.t_s, t_all[ref])
        t, acc = buf.window(now - 0.5, now - 0.2)
        sel = (t_all >= now - 0.5) & (t_all <= now - 0.2) & (t_all >= kept_from)
        np.testing.assert_array_equal(acc, acc_all[sel])
    assert len(buf._t) <= 1024  # bounded by the kept span, not the history


def test_out_of_order_samples_are_dropped_and_counted():
    buf = SampleBuffer()
    buf.extend([0.0, 0.01, 0.02], np.zeros((3, 3)))
    buf.extend([0.015, 0.03], np.ones((2, 3)))
    np.testing.assert_array_equal(buf.t_s, [0.0, 0.01, 0.02, 0.03])
    assert buf.out_of_order == 1
