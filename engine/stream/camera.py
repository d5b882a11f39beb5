"""The overhead camera's track, aligned to the synthesis frame clock.

Why: camera fixes come at their own rate (12-30 fps) and with their own delay. Each synthesis frame must get the
fix for ITS time — linear interpolation between the two fixes that bracket the frame — not whatever fix happened
to be newest when the frame was pushed (that made live poses depend on network timing, and a batch of frames all
shared one position). A frame bracketed by fixes more than ``max_gap_s`` apart, or by a fix without a position
(the tracker lost the player), gets no position: the search steps on the accelerometers alone, exactly as it
does offline on the same recorded fixes."""
from __future__ import annotations

import math

import numpy as np

from engine.mocap import wrap_angle


class CameraTrack:
    """Timestamped fixes in (any batching, time order per fix); `at(frame times)` -> positions and headings."""

    def __init__(self, max_gap_s: float = 0.5, history_s: float = 2.0) -> None:
        self.max_gap_s = max_gap_s
        self.history_s = history_s
        self._t = np.zeros(0)
        self._xy = np.zeros((0, 2))
        self._heading = np.zeros(0)

    def add(self, t_s: float, position_m: object | None, heading_rad: float | None = None) -> None:
        """One camera observation at gateway time ``t_s``: court ``position_m`` [x, y] (None while the tracker
        has no player) and heading (None if unknown). Fixes not after the newest are dropped."""
        if len(self._t) and t_s <= self._t[-1]:
            return
        xy = (np.full(2, np.nan) if position_m is None else np.asarray(position_m, float).reshape(-1)[:2])
        self._t = np.append(self._t, float(t_s))
        self._xy = np.vstack([self._xy, xy])
        self._heading = np.append(self._heading, np.nan if heading_rad is None else float(heading_rad))

    @property
    def newest_s(self) -> float:
        return float(self._t[-1]) if len(self._t) else -math.inf

    @property
    def empty(self) -> bool:
        return not len(self._t)

    def at(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(positions (F, 2) m, headings (F,) rad) at frame times ``t_s``; NaN where not bracketed by two fixes
        at most ``max_gap_s`` apart that both carry the value."""
        t_s = np.asarray(t_s, float)
        pos = np.full((len(t_s), 2), np.nan)
        head = np.full(len(t_s), np.nan)
        t = self._t
        if len(t) == 0:
            return pos, head
        if len(t) == 1:
            exact = t_s == t[0]
            pos[exact], head[exact] = self._xy[0], self._heading[0]
            return pos, head
        i = np.clip(np.searchsorted(t, t_s, side="right") - 1, 0, len(t) - 2)  # t[i] <= x < t[i+1]
        inside = (t_s >= t[0]) & (t_s <= t[-1]) & (t[i + 1] - t[i] <= self.max_gap_s)
        w = np.where(inside, (t_s - t[i]) / (t[i + 1] - t[i]), 0.0)
        h0, h1 = self._heading[i], self._heading[i + 1]
        pos[inside] = (self._xy[i] + (self._xy[i + 1] - self._xy[i]) * w[:, None])[inside]
        head[inside] = wrap_angle(h0 + wrap_angle(h1 - h0) * w)[inside]
        j = np.minimum(np.searchsorted(t, t_s, side="left"), len(t) - 1)
        on_fix = t[j] == t_s  # exactly on a fix: its own value (a NaN neighbour must not erase it)
        pos[on_fix], head[on_fix] = self._xy[j[on_fix]], self._heading[j[on_fix]]
        return pos, head

    def trim_before(self, t_s: float) -> None:
        """Forget fixes older than ``t_s - history_s``, keeping the one at or before it (it still brackets)."""
        cut = max(0, int(np.searchsorted(self._t, t_s - self.history_s, side="right")) - 1)
        if cut:
            self._t, self._xy, self._heading = self._t[cut:], self._xy[cut:], self._heading[cut:]
