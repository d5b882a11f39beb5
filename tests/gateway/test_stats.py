"""Per-sensor counters: loss from counter gaps, duplicates, u32 counter wrap, reboot, rate over a window."""
from __future__ import annotations

import pytest

from gateway.stats import COUNTER_MODULUS, SensorStats


def test_gap_duplicate_and_wrap():
    s = SensorStats(0, nominal_hz=100)
    s.on_batch(COUNTER_MODULUS - 10, 5, 0.0)
    s.on_batch(COUNTER_MODULUS - 5, 5, 0.05)  # ends exactly at the wrap
    s.on_batch(3, 5, 0.1)  # counters 0..2 lost across the wrap
    assert (s.received, s.lost, s.duplicates) == (15, 3, 0)
    s.on_batch(5, 3, 0.12)  # a retransmitted/reordered part: 5, 6, 7 already counted
    assert (s.received, s.lost, s.duplicates) == (18, 3, 3)
    s.on_batch(8, 5, 0.15)  # continues after the highest counter seen, no new loss
    assert s.lost == 3 and s.loss_pct == pytest.approx(100 * 3 / 26)


def test_reboot_is_not_loss_and_rate_uses_the_window():
    s = SensorStats(1)
    s.on_batch(1000, 10, 0.0)
    s.restart_counter()
    s.on_batch(0, 10, 0.1)
    assert (s.lost, s.counter_resets) == (0, 1)
    s.update_rate(0.5, rate_window_s=1.0)
    assert s.rate_hz == 0.0  # window not yet elapsed
    for i in range(10):
        s.on_batch(10 + 10 * i, 10, 0.2 + 0.1 * i)
    s.update_rate(1.0, rate_window_s=1.0)
    assert s.rate_hz == pytest.approx(120 / 1.0)  # every sample since the first batch at t = 0
