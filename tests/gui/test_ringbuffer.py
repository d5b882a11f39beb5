"""Ring buffers keep exactly the newest samples in order; min-max decimation keeps every peak."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from gui.ringbuffer import SampleRing, minmax_decimate


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, 40), min_size=1, max_size=20), st.integers(1, 50))
def test_ring_holds_newest_samples_in_order(batch_sizes, capacity):
    ring = SampleRing(capacity, 3)
    t_all = np.arange(sum(batch_sizes), dtype=float)
    i = 0
    for n in batch_sizes:
        ring.append(t_all[i:i + n], np.c_[t_all[i:i + n], -t_all[i:i + n], 2 * t_all[i:i + n]])
        i += n
    t, v = ring.data()
    expect = t_all[-capacity:] if capacity < len(t_all) else t_all
    np.testing.assert_array_equal(t, expect)
    np.testing.assert_array_equal(v, np.c_[expect, -expect, 2 * expect])
    assert ring.total == len(t_all)
    assert ring.latest_time() == (t_all[-1] if len(t_all) else None)


def test_decimation_keeps_spikes_and_newest_sample():
    t = np.arange(10_007) * 0.001
    y = np.zeros((len(t), 2))
    y[5003, 0] = 11.5   # a one-sample impact
    y[17, 1] = -7.0
    td, yd = minmax_decimate(t, y, 400)
    assert len(td) <= 400
    assert yd[:, 0].max() == 11.5 and yd[:, 1].min() == -7.0
    assert td[-1] == t[-1]
    assert np.all(np.diff(td) >= 0)


def test_decimation_passthrough_when_small():
    t = np.arange(10.0)
    td, yd = minmax_decimate(t, t, 100)
    np.testing.assert_array_equal(td, t)
    np.testing.assert_array_equal(yd[:, 0], t)
