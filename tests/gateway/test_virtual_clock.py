"""Clock alignment through the real reader in virtual time: +-100 ppm crystal, random tick offset, 0-20 ms
delivery jitter, radio loss and bursts; 150 s emulated per case (the 1 h run is in bench/bench_gateway.py)."""
from __future__ import annotations

import numpy as np
import pytest

from firmware_protocol.emulator import StationConfig
from firmware_protocol.emulator.virtual_time import run_virtual_station


@pytest.mark.parametrize("drift_ppm, seed", [(100.0, 1), (-100.0, 2)])
def test_time_error_below_1ms_p99_after_warmup(drift_ppm, seed):
    rng = np.random.default_rng(seed)
    config = StationConfig(drift_ppm=drift_ppm, tick_offset=int(rng.integers(0, 2**32)), radio_loss=0.01,
                           burst_probability=0.01, seed=seed)
    run = run_virtual_station(config, duration_s=150.0, jitter_s=0.020, seed=seed)
    assert run.received == run.delivered > 80_000  # nothing lost in the gateway
    late = run.error_after(30.0)
    assert np.percentile(late, 99) < 1e-3, f"p99 {np.percentile(late, 99) * 1e3:.3f} ms"
    assert run.status["clock"]["locked"]
    assert run.status["clock"]["skew_ppm"] == pytest.approx(-drift_ppm, abs=10)
    assert np.abs(run.error_s).max() < 0.05  # even during warm-up the estimate is never far off


def test_tick_wrap_during_run_is_seamless():
    """1 MHz ticks starting 20 s before the u32 wrap: no reset, no error spike across the wrap."""
    config = StationConfig(drift_ppm=40.0, tick_offset=2**32 - 20_000_000, seed=5)
    run = run_virtual_station(config, duration_s=60.0, jitter_s=0.010, seed=5)
    assert run.status["clock"]["wraps"] == 1 and run.status["clock"]["resets"] == 0
    assert run.received == run.delivered
    assert np.percentile(run.error_after(30.0), 99) < 1e-3
