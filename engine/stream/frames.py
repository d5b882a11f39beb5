"""Resample asynchronous, timestamped per-sensor sample streams onto the synthesis frame clock.

Why one module: the console's live worker and `courtside synthesize` must turn the same samples into the same
frames, or a take gives different poses live and offline. Everything here is a function of the samples'
timestamps and values only — never of how they were batched, when they arrived or where a buffer started:

* The frame clock is absolute: frame ``k`` is at ``t = k / rate_hz`` on the gateway clock (an integer index, never
  an accumulated float), so a live session and an offline run put frames at bit-identical times.
* A frame is the mean of the linearly interpolated signal over one frame period centred on it — an anti-alias
  box filter before decimating (100 Hz -> 30 Hz would otherwise fold 15-50 Hz content into the band, as plain
  point sampling does), exact on any linear stretch of signal whatever the sample times, and close to what the
  graph's virtual sensors saw (accelerations of 30 Hz mocap). The integral is summed from the samples inside
  the window only (not from a running cumulative sum), so its rounding does not depend on history.
* Dropouts are never interpolated across: a frame whose window touches a gap of more than ``max_gap_s`` in any
  sensor is *invalid*; its accelerations are NaN and the caller steps the search without them.
* Live, a frame is produced once every live sensor has samples past its window (nothing is extrapolated); a
  sensor more than ``wait_s`` behind the newest one stops holding frames back, so a dead sensor stalls synthesis
  for ``wait_s`` once and then degrades it instead of freezing it. A sensor that is merely late (a loaded
  gateway, a slow network) is waited for up to ``wait_s`` (>= ``max_gap_s``), so its frames come out exactly as
  offline; a frame produced without a sensor that then turns out to have been only late (by more than
  ``wait_s``) is the one case where live and offline differ.
* Angular rate (rad/s) goes through the same box filter as the accelerations. An orientation quaternion is
  averaged the same way after its samples are made sign-continuous (each sample's sign chosen to agree with the
  previous sample of its sensor: q and -q are one rotation, and a window straddling a flip would average to
  nothing), then normalised and given a canonical sign (w >= 0). Why a normalised mean and not a slerp at the
  frame time: the frame's orientation is then the same window average its accelerations are (a sensor turning
  within the frame period sees both smeared alike), it needs no special case at window edges, and between
  samples 1/100 s apart it differs from the true rotational mean by far less than a filter's tilt error. The
  sign chain depends on where a stream started, but only as a whole-window sign (IEEE arithmetic is exact under
  negation), which the canonical sign removes: live and offline stay bit for bit identical.
  A sample whose quaternion is missing (NaN) leaves that sensor's frames it touches NaN in ``quat_wxyz`` only.
"""
from __future__ import annotations

import math
from collections.abc import Hashable, Sequence
from dataclasses import dataclass

import numpy as np

_EPS = 1e-9  # tolerance (in frames or seconds) for times that land exactly on a boundary


def frame_at_or_after(t_s: float, rate_hz: float) -> int:
    """Index of the first frame at or after ``t_s`` on the absolute frame clock ``t = k / rate_hz``."""
    return int(math.ceil(t_s * rate_hz - _EPS))


ACC, GYRO, QUAT = slice(0, 3), slice(3, 6), slice(6, 10)  # columns of the resampler's per-sample rows
N_COLUMNS = 10


@dataclass
class FrameBatch:
    """Frames ``index`` (F,) int64 at ``t_s`` (F,), accelerations ``acc_g`` (F, S, 3) (NaN where invalid) and
    ``valid`` (F,) bool (False: some sensor's window touches a dropout); ``quat_wxyz`` (F, S, 4) unit quaternions
    sensor -> device earth (Z up, yaw per sensor) and ``gyro_rps`` (F, S, 3) rad/s in the sensor frame, each None
    when no sensor streams it and NaN where invalid or where that sensor has none."""

    index: np.ndarray
    t_s: np.ndarray
    acc_g: np.ndarray
    valid: np.ndarray
    quat_wxyz: np.ndarray | None = None
    gyro_rps: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.index)

    @classmethod
    def empty(cls, n_sensors: int) -> "FrameBatch":
        return cls(np.zeros(0, np.int64), np.zeros(0), np.zeros((0, n_sensors, 3)), np.zeros(0, bool))

    @classmethod
    def concatenate(cls, batches: Sequence["FrameBatch"], n_sensors: int) -> "FrameBatch":
        batches = [b for b in batches if len(b)]
        if not batches:
            return cls.empty(n_sensors)
        fields = [np.concatenate([getattr(b, f) for b in batches]) for f in ("index", "t_s", "acc_g", "valid")]
        for name, width in (("quat_wxyz", 4), ("gyro_rps", 3)):
            parts = [getattr(b, name) for b in batches]
            fields.append(None if all(p is None for p in parts) else np.concatenate(
                [np.full((len(b), n_sensors, width), np.nan) if p is None else p for b, p in zip(batches, parts)]))
        return cls(*fields)


class FrameResampler:
    """Feed batches per sensor (any order, any size); pull the newly complete frames as a `FrameBatch`.

    ``history_s`` of samples are kept behind the next frame so `start_at` can move the clock back a little (a
    recording-start notice that arrives late still starts the take's synthesis at its defined frame)."""

    def __init__(self, sensors: Sequence[Hashable], rate_hz: float, max_gap_s: float = 0.25, wait_s: float = 1.0,
                 history_s: float = 2.0) -> None:
        if max_gap_s < 1.0 / rate_hz:
            raise ValueError(f"max_gap_s {max_gap_s} must be at least one frame period ({1.0 / rate_hz:.4f} s)")
        if wait_s < max_gap_s:
            raise ValueError(f"wait_s {wait_s} must be at least max_gap_s {max_gap_s} (or live frames would be "
                             "marked invalid for gaps offline sees as none)")
        self.wait_s = wait_s
        self.sensors = list(sensors)
        self.rate_hz = float(rate_hz)
        self.max_gap_s = max_gap_s
        self.history_s = history_s
        self._t: dict[Hashable, np.ndarray] = {s: np.zeros(0) for s in self.sensors}
        # per sample: acceleration, angular rate, sign-continuous quaternion (NaN where the sensor has none)
        self._v: dict[Hashable, np.ndarray] = {s: np.zeros((0, N_COLUMNS)) for s in self.sensors}
        self._quat_ref: dict[Hashable, np.ndarray | None] = {s: None for s in self.sensors}  # newest valid quaternion
        self.has_quat = self.has_gyro = False  # some sensor has streamed the channel
        self._next: int | None = None  # index of the next frame to produce
        self._hi_last = -np.inf  # end of the last produced frame's window
        self.frames_out = 0
        self.frames_invalid = 0
        # samples that arrived after frames spanning their time were produced (a sensor later than wait_s): the
        # frames they belong to were decided without them, so live may differ from offline there
        self.late_samples = 0

    # -- input ----------------------------------------------------------------------------------------------------
    def add(self, sensor: Hashable, t_s: np.ndarray, acc_g: np.ndarray, quat_wxyz: np.ndarray | None = None,
            gyro_rps: np.ndarray | None = None) -> None:
        """Append a batch (ignored for sensors not in the list), with the sensor's orientation (N, 4) and angular
        rate (N, 3) when it streams them. A sample not after every earlier sample of its sensor is dropped
        (duplicates, a clock map that stepped back): a running maximum over the whole stream, so the same samples
        are dropped however the stream is batched."""
        if sensor not in self._t:
            return
        t_s = np.asarray(t_s, float).reshape(-1)
        newest = self._t[sensor][-1] if len(self._t[sensor]) else -np.inf
        keep = t_s > np.maximum.accumulate(np.r_[newest, t_s])[:-1]
        self.late_samples += int((t_s[keep] <= self._hi_last).sum())
        if not keep.any():
            return
        rows = np.full((int(keep.sum()), N_COLUMNS), np.nan)
        rows[:, ACC] = np.asarray(acc_g, float).reshape(-1, 3)[keep]
        if gyro_rps is not None:
            rows[:, GYRO] = np.asarray(gyro_rps, float).reshape(-1, 3)[keep]
            self.has_gyro = True
        if quat_wxyz is not None:
            rows[:, QUAT] = self._sign_continuous(sensor, np.asarray(quat_wxyz, float).reshape(-1, 4)[keep])
            self.has_quat = True
        self._t[sensor] = np.concatenate([self._t[sensor], t_s[keep]])
        self._v[sensor] = np.concatenate([self._v[sensor], rows])

    def _sign_continuous(self, sensor: Hashable, quat: np.ndarray) -> np.ndarray:
        """Flip each valid quaternion to agree in sign with the sensor's previous valid one (NaN rows kept)."""
        ok = ~np.isnan(quat).any(axis=1)
        q = quat[ok]
        if not len(q):
            return quat
        ref = self._quat_ref[sensor]
        prev = np.vstack([q[:1] if ref is None else ref[None], q[:-1]])
        flips = np.cumprod(np.where(np.einsum("ij,ij->i", q, prev) < 0, -1.0, 1.0))
        out = quat.copy()
        out[ok] = q * flips[:, None]
        self._quat_ref[sensor] = out[ok][-1]
        return out

    def start_at(self, t_s: float | None) -> None:
        """Produce frames from the first frame at or after ``t_s`` on (None: from the first frame every sensor's
        data covers). A start more than ``history_s`` before every sensor's first sample is one this resampler
        never had data for (it joined later): frames then start where every sensor's data does."""
        self._next = None if t_s is None else frame_at_or_after(t_s, self.rate_hz)
        self._hi_last, self.late_samples = -np.inf, 0  # the frames from here on are produced afresh

    # -- state ----------------------------------------------------------------------------------------------------
    @property
    def next_frame(self) -> int | None:
        return self._next

    @property
    def newest_s(self) -> float:
        """Newest sample time over all sensors (-inf before any)."""
        return max((t[-1] for t in self._t.values() if len(t)), default=-np.inf)

    # -- output ---------------------------------------------------------------------------------------------------
    def frames(self, until_s: float = np.inf, max_frames: int | None = None) -> FrameBatch:
        """All newly complete frames with ``t <= until_s`` (the caller's other streams, e.g. the camera, may hold
        frames back), at most ``max_frames`` of them (the rest come on the next call: a live caller whose engine
        is slower than real time stays responsive); trims history."""
        if any(len(t) == 0 for t in self._t.values()):  # every worn sensor must have spoken once
            return FrameBatch.empty(len(self.sensors))
        rate = self.rate_hz
        lasts = np.array([t[-1] for t in self._t.values()])
        live = lasts >= lasts.max() - self.wait_s
        # the last frame whose whole window [k - 1/2, k + 1/2] / rate every live sensor has covered
        last = int(math.floor(lasts[live].min() * rate - 0.5 + _EPS))
        if until_s < np.inf:
            last = min(last, int(math.floor(until_s * rate + _EPS)))
        covered = int(math.ceil(max(t[0] for t in self._t.values()) * rate + 0.5 - _EPS))
        if self._next is None:  # first frame whose whole window lies after every sensor's first sample
            self._next = covered
        elif min(t[0] for t in self._t.values()) - self.history_s > self._next / rate:
            # asked to start before anything this resampler could ever have had (a console that joins a take
            # minutes after it started): start where the data does, instead of pushing every frame since the
            # take's start blind (an hour-old take would be 108 000 empty frames before the first real one)
            self._next = covered
        if max_frames is not None:
            last = min(last, self._next + max_frames - 1)
        if last < self._next:
            return FrameBatch.empty(len(self.sensors))
        index = np.arange(self._next, last + 1, dtype=np.int64)
        times = index / rate
        lo, hi = (index - 0.5) / rate, (index + 0.5) / rate
        out = np.empty((len(index), len(self.sensors), N_COLUMNS))
        valid = np.ones(len(index), bool)
        for k, s in enumerate(self.sensors):
            # only the samples bracketing and inside these windows (the results depend on nothing else)
            t, v = self._t[s], self._v[s]
            i0 = max(0, int(np.searchsorted(t, lo[0], side="right")) - 1)
            i1 = int(np.searchsorted(t, hi[-1], side="left")) + 1
            out[:, k] = box_mean(t[i0:i1], v[i0:i1], lo, hi)
            valid &= window_covered(t[i0:i1], lo, hi, self.max_gap_s)
        out[~valid] = np.nan  # never a made-up value across a dropout
        self._next = last + 1
        self._hi_last = float(hi[-1])
        self._trim((self._next - 0.5) / rate - self.history_s)
        self.frames_out += len(index)
        self.frames_invalid += int((~valid).sum())
        quat = _unit_canonical(out[..., QUAT]) if self.has_quat else None
        gyro = np.ascontiguousarray(out[..., GYRO]) if self.has_gyro else None
        return FrameBatch(index, times, np.ascontiguousarray(out[..., ACC]), valid, quat, gyro)

    def _trim(self, keep_from_s: float) -> None:
        """Drop samples before ``keep_from_s``, keeping the one at or before it so it stays bracketed."""
        for s in self.sensors:
            t = self._t[s]
            cut = max(0, int(np.searchsorted(t, keep_from_s, side="right")) - 1)
            if cut:
                self._t[s], self._v[s] = t[cut:], self._v[s][cut:]


def _unit_canonical(quat: np.ndarray) -> np.ndarray:
    """Window means of sign-continuous quaternions (..., 4) -> unit quaternions with w >= 0 (NaN stays NaN)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        q = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def uniform_streams(acc_g: np.ndarray, fps_in: float, rate_hz: float, t0_s: float = 0.0,
                    quat_wxyz: np.ndarray | None = None, gyro_rps: np.ndarray | None = None
                    ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]]:
    """Per sensor, the samples (t_s, acc_g, quat_wxyz or None, gyro_rps or None) that `resample_uniform` feeds
    its resampler from a uniformly sampled take (T, S, 3) at ``fps_in`` starting at ``t0_s``: NaN rows dropped,
    the first and last reading each held half a frame of ``rate_hz`` (at least one input period) beyond the
    data. Shared with the console's playback of such a take, so its live frames are these frames."""
    acc_g = np.asarray(acc_g, float)
    dt = 1.0 / fps_in
    t = t0_s + np.arange(len(acc_g)) * dt
    extras = [np.asarray(a, float) for a in (quat_wxyz, gyro_rps) if a is not None]
    hold = max(dt, 0.5 / rate_hz)
    out = []
    for k in range(acc_g.shape[1]):
        ok = ~np.isnan(acc_g[:, k]).any(axis=1)
        tk = t[ok]
        vk = np.concatenate([acc_g[ok, k]] + [a[ok, k] for a in extras], axis=1)
        if len(tk) and ok[0]:
            tk, vk = np.r_[tk[0] - hold, tk], np.vstack([vk[:1], vk])
        if len(tk) and ok[-1]:
            tk, vk = np.r_[tk, tk[-1] + hold], np.vstack([vk, vk[-1:]])
        out.append((tk, vk[:, :3], vk[:, 3:7] if quat_wxyz is not None else None,
                    vk[:, -3:] if gyro_rps is not None else None))
    return out


def resample_uniform(acc_g: np.ndarray, fps_in: float, rate_hz: float, max_gap_s: float = 0.25,
                     t0_s: float = 0.0, quat_wxyz: np.ndarray | None = None,
                     gyro_rps: np.ndarray | None = None) -> FrameBatch:
    """A whole uniformly sampled stream (T, S, 3) at ``fps_in`` starting at ``t0_s``, through the same resampler
    (NaN rows are dropouts: they are removed, so the frames around them come out invalid); ``quat_wxyz``
    (T, S, 4) and ``gyro_rps`` (T, S, 3) of the same samples ride along (a NaN there is a missing value of that
    channel only).

    At the take's two ends each sensor's first and last reading is held for half a frame (at least one input
    period), so the frames there, whose windows reach half a frame beyond the data, exist: a take of T samples at
    the graph rate gives T frames, one at 120 Hz as many as the polyphase resampler used to (ceil(T / 4) at 30 Hz)."""
    gap = max(max_gap_s, 1.0 / rate_hz, 1.5 * (1.0 / fps_in))
    res = FrameResampler(range(np.shape(acc_g)[1]), rate_hz, gap, wait_s=gap)
    for k, stream in enumerate(uniform_streams(acc_g, fps_in, rate_hz, t0_s, quat_wxyz, gyro_rps)):
        res.add(k, *stream)
    res.start_at(t0_s)
    return res.frames(until_s=t0_s + (len(acc_g) - 1) * (1.0 / fps_in) if len(acc_g) else -np.inf)


def _interp_at(t: np.ndarray, v: np.ndarray, i: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Linear interpolation of samples (t, v) at ``x`` inside interval ``i`` ([t[i], t[i+1]])."""
    w = ((x - t[i]) / (t[i + 1] - t[i]))[:, None]
    return v[i] + (v[i + 1] - v[i]) * w


def box_mean(t: np.ndarray, v: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Mean of the piecewise-linear interpolant of samples ``v`` (N, C) at ``t`` (N,) over each window
    [lo, hi] (F,), windows clipped to the sampled span (a window outside it gives the end value).

    Each window's integral is the partial trapezoids at its two ends plus the whole sample intervals between,
    added in time order from the window's own samples: the result depends only on the samples bracketing and
    inside the window, never on how much history the buffer holds (so live and offline agree to the bit)."""
    v = np.asarray(v, float).reshape(len(t), -1)
    if len(t) < 2:
        return np.repeat(v[:1], len(lo), axis=0)
    lo, hi = np.clip(lo, t[0], t[-1]), np.clip(hi, t[0], t[-1])
    last = len(t) - 2
    i_lo = np.clip(np.searchsorted(t, lo, side="right") - 1, 0, last)  # t[i] <= lo < t[i+1]
    i_hi = np.clip(np.searchsorted(t, hi, side="left") - 1, 0, last)   # t[i] < hi <= t[i+1]
    v_lo, v_hi = _interp_at(t, v, i_lo, lo), _interp_at(t, v, i_hi, hi)
    same = (i_lo == i_hi)[:, None]
    # one interval: the trapezoid lo..hi; otherwise lo..t[i_lo+1], whole intervals, t[i_hi]..hi
    total = np.where(same, 0.5 * (v_lo + v_hi) * (hi - lo)[:, None],
                     0.5 * (v_lo + v[i_lo + 1]) * (t[i_lo + 1] - lo)[:, None])
    area = 0.5 * (v[1:] + v[:-1]) * np.diff(t)[:, None]  # (N-1, C) whole-interval trapezoids
    span = int((i_hi - i_lo).max())
    for j in range(1, span):  # intervals i_lo+1 .. i_hi-1, in time order (a handful per window)
        inside = (i_lo + j < i_hi)[:, None]
        total = total + np.where(inside, area[np.minimum(i_lo + j, last)], 0.0)
    total = total + np.where(same, 0.0, 0.5 * (v[i_hi] + v_hi) * (hi - t[i_hi])[:, None])
    width = (hi - lo)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(width > 0, total / width, v_lo)


def window_covered(t: np.ndarray, lo: np.ndarray, hi: np.ndarray, max_gap_s: float, tol_s: float = _EPS) -> np.ndarray:
    """(F,) True where samples span each window [lo, hi] with no gap longer than ``max_gap_s`` touching it.

    A gap longer than the window cannot lie strictly inside it, so checking the sample intervals that contain
    ``lo`` and ``hi`` is enough (the resampler guarantees max_gap_s >= one frame period)."""
    covered = (t[0] <= lo + tol_s) & (t[-1] >= hi - tol_s)
    if len(t) < 2:
        return covered & (hi - lo <= tol_s)
    i_lo = np.clip(np.searchsorted(t, lo + tol_s, side="right") - 1, 0, len(t) - 2)
    i_hi = np.clip(np.searchsorted(t, hi - tol_s, side="left") - 1, 0, len(t) - 2)
    dt = np.diff(t)
    return covered & (dt[i_lo] <= max_gap_s) & (dt[i_hi] <= max_gap_s)
