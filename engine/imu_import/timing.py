"""Sample times of a recorded stream: checked before anything is allocated from them, then one common grid.

Why checked first (issue 30): the grid is allocated from the times, so one typo'd timestamp (1e10 ms) or a rate
off by a unit made the import ask for gigabytes, and a clock reset was silently sorted into an interleaved take.
The rules, with the limits of `engine.recording_limits`:

* times are finite and never go back: a step back is a device clock reset (x-IMU3 after a power cut) or rows out
  of order, refused naming the line, since which half comes first is not in the file; equal times keep the first
  sample;
* a stream spans at most `MAX_TAKE_S`, and its median rate lies in `MIN_RATE_HZ` .. `MAX_RATE_HZ`;
* between two usable accelerations there is at most `MAX_GAP_S` (longer gaps are refused, not interpolated);
  orientation and gyro are resampled between neighbouring samples only (`neighbours_s`): a missing one stays NaN;
* the grid holds at most a few samples per input row (so memory is bounded by the input's size too)."""
from __future__ import annotations

import numpy as np

from engine.errors import CourtsideError
from engine.imu_import.origin import Origin, stream_error
from engine.recording_limits import MAX_GAP_S, MAX_TAKE_S, rate_problem

GRID_ROWS_PER_INPUT_ROW = 4  # a grid longer than this many samples per input row means irregular times


def check_times(t_s: np.ndarray, origin: Origin | None, label: str) -> None:
    """Refuse non-finite times, a step back, and a span beyond `MAX_TAKE_S` (see the module doc)."""
    t = np.asarray(t_s, float)
    bad = ~np.isfinite(t)
    if bad.any():
        i = int(np.argmax(bad))
        raise stream_error(origin, label, i, f"time {float(t[i])} is not a number")
    step = np.diff(t)
    if (step < 0).any():
        i = int(np.argmax(step < 0)) + 1
        raise stream_error(origin, label, i, f"time goes back from {t[i - 1]:.6g} s to {t[i]:.6g} s (a device "
                                             "clock reset, or rows out of order): split the recording there")
    if len(t) > 1 and t[-1] - t[0] > MAX_TAKE_S:
        i = int(np.argmax(step)) + 1
        raise stream_error(origin, label, i, f"the stream would span {(t[-1] - t[0]) / 3600:.4g} h, more than the "
                                             f"{MAX_TAKE_S / 3600:g} h a take may last; its largest time step is "
                                             f"here ({t[i - 1]:.6g} s -> {t[i]:.6g} s): a typo'd timestamp, or a "
                                             "wrong --time-unit?")


def sample_rate(t_s: np.ndarray, origin: Origin | None, label: str) -> float:
    """Median rate (Hz) of strictly increasing times, refused outside the plausible range."""
    step = float(np.median(np.diff(np.asarray(t_s, float))))
    rate = 1.0 / step
    problem = rate_problem(rate)
    if problem:
        raise stream_error(origin, label, None, f"sample rate {problem} (median time step {step:.6g} s): a wrong "
                                                "--time-unit or --rate?")
    return rate


def check_gaps(t_s: np.ndarray, origin: Origin | None, label: str) -> None:
    """Refuse a gap longer than `MAX_GAP_S` between consecutive usable samples (times ``t_s``, origin of those
    samples)."""
    step = np.diff(np.asarray(t_s, float))
    if len(step) and step.max() > MAX_GAP_S:
        i = int(np.argmax(step)) + 1
        raise stream_error(origin, label, i, f"no acceleration for {step[i - 1]:.4g} s before this sample "
                                             f"({t_s[i - 1]:.6g} s -> {t_s[i]:.6g} s), more than the "
                                             f"{MAX_GAP_S:g} s that are bridged: split the recording at the gap")


def common_grid(spans_s: list[tuple[float, float]], rate_hz: float, input_rows: int) -> np.ndarray:
    """Times (s) at ``rate_hz`` over the span every stream covers; refused when the streams do not overlap or the
    grid would be far longer than the input (irregular times)."""
    t0, t1 = max(s[0] for s in spans_s), min(s[1] for s in spans_s)
    if not t1 > t0:
        raise CourtsideError("the sensors' recordings do not overlap in time")
    n = int(np.floor((t1 - t0) * rate_hz + 1e-9)) + 1
    if n > GRID_ROWS_PER_INPUT_ROW * input_rows + 16:
        raise CourtsideError(f"{n} samples at {rate_hz:g} Hz from {input_rows} input rows: the times are too "
                             "irregular to put on one grid")
    return t0 + np.arange(n) / rate_hz


def neighbours_s(t_s: np.ndarray) -> float:
    """The longest step `bridge` may interpolate over for orientation and gyro: 1.5 median steps of the stream's
    own rows, so they are resampled between neighbouring samples only and a missing one stays missing."""
    return 1.5 * float(np.median(np.diff(np.asarray(t_s, float))))


def bridge(grid_s: np.ndarray, t_s: np.ndarray, values: np.ndarray, max_gap_s: float) -> np.ndarray:
    """``values`` (N, K) linearly interpolated at ``grid_s`` from its finite rows; NaN at grid times outside those
    rows' span or between two of them more than ``max_gap_s`` apart (never extrapolated, never bridged
    further)."""
    v = np.asarray(values, float)
    ok = np.isfinite(v).all(axis=1)
    t_ok, v_ok = np.asarray(t_s, float)[ok], v[ok]
    out = np.full((len(grid_s), v.shape[1]), np.nan)
    if not len(t_ok):
        return out
    after = np.searchsorted(t_ok, grid_s, side="right")
    before_t = t_ok[np.clip(after - 1, 0, len(t_ok) - 1)]
    after_t = t_ok[np.clip(after, 0, len(t_ok) - 1)]
    slack = 1e-9 * max(1.0, abs(float(t_ok[-1])))  # the grid's last time may exceed the last sample by rounding
    usable = (grid_s >= t_ok[0] - slack) & (grid_s <= t_ok[-1] + slack) & (after_t - before_t <= max_gap_s)
    for k in range(v.shape[1]):
        out[usable, k] = np.interp(grid_s[usable], t_ok, v_ok[:, k])
    return out


def bridge_quaternions(grid_s: np.ndarray, t_s: np.ndarray, q_wxyz: np.ndarray, max_gap_s: float) -> np.ndarray:
    """`bridge` for unit quaternions (NaN rows missing): consecutive present rows are put in one hemisphere
    first, the result is renormalised (nlerp); missing stays NaN."""
    q = np.asarray(q_wxyz, float).copy()
    present = np.flatnonzero(np.isfinite(q).all(axis=1))
    if len(present) > 1:
        rows = q[present]
        flip = np.cumprod(np.r_[1.0, np.where(np.sum(rows[1:] * rows[:-1], axis=1) < 0, -1.0, 1.0)])
        q[present] = rows * flip[:, None]
    out = bridge(grid_s, t_s, q, max_gap_s)
    return out / np.linalg.norm(out, axis=1, keepdims=True)
