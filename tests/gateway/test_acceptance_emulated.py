"""Acceptance: 4 emulated stations x 6 sensors x 100 Hz over real ptys, with radio loss, wire corruption, unplug/replugs
and the synthetic court camera, at 2x real time; the harness and its criteria are in `bench.support.acceptance`
(shared with `bench/bench_gateway.py --acceptance-minutes 10`)."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from bench.support.acceptance import AcceptanceRun, cell_minima, run_acceptance


def judge(run: AcceptanceRun) -> None:
    """Print the figures; fail on any missed criterion. On a starved host (its fastest clock beacons already late:
    `AcceptanceRun.host_starved`, itself tested below on known answers) the clock limits measure the machine, not
    the estimator: they are reported as a warning there, and every other criterion (exact recording, reconnect,
    camera) still fails the test."""
    print(run.summary())
    failures = run.failures()
    if run.host_starved:
        clock = [f for f in failures if "clock error" in f or f.startswith("HOST STARVED")]
        failures = [f for f in failures if f not in clock]
        warnings.warn(f"acceptance on a starved host ({run.host_report()}): "
                      f"{'; '.join(clock) if clock else 'clock within its limits'}", stacklevel=2)
    assert not failures, run.summary()


@pytest.mark.slow
@pytest.mark.alone  # its 2-ms clock limits measure real-time delivery: a GUI test beside it took 2.095 ms in CI
def test_four_stations_exact_recording_clock_reconnect_and_camera(tmp_path):
    """One minute, two unplugs on two stations (the 3- and 10-minute runs are benchmarks:
    `bench/bench_gateway.py --acceptance-minutes 3 --acceptance-unplugs 3`, docs/gateway.md "Acceptance")."""
    judge(run_acceptance(tmp_path, span_s=60.0, speed=2.0, n_unplugs=2))


def test_cell_minima_and_the_starved_host_diagnosis():
    """The scoring helpers on known answers: per-cell minima, and a clock failure on a host whose fastest beacons
    were late is labelled as the host's, while the same failure on a prompt host is not (it blames the clock)."""
    t = np.array([0.1, 0.5, 0.9, 1.2, 3.7, 3.8])
    assert cell_minima(t, np.array([5.0, 2.0, 7.0, 4.0, 9.0, 1.0]), 1.0).tolist() == [2.0, 4.0, 1.0]
    run = AcceptanceRun(60.0, 2.0, [], wall_s=30.0, cpu_s=20.0, other_cpu_s=30.0,
                        online_err_s=np.full(100, 1.5e-3), offline_err_s=np.full(100, 0.2e-3))
    run.beacon_floor_s = np.array([0.1e-3, 0.2e-3, 0.3e-3])
    assert not run.host_starved
    assert any("online p99 clock error 1.500 ms" in f for f in run.failures())
    assert not any("HOST STARVED" in f for f in run.failures())
    run.beacon_floor_s = np.array([0.1e-3, 0.6e-3, 2.0e-3])
    assert run.host_starved
    assert any("HOST STARVED" in f and "other processes used 1.00 of" in f for f in run.failures())
    run.online_err_s = np.full(100, 0.3e-3)  # the clock within its limit: no clock failure to explain
    assert not any("clock" in f or "HOST" in f for f in run.failures())
