"""Showing every synthesized pose at the synthesis rate, rather than the newest one at each look.

Why: the sensors' radio packets carry a few samples each, so the engine gets new data every 40-50 ms and decides
poses in bursts of one or two. A view that draws the newest pose at each refresh tick showed ~20 of the 30
poses a second (`bench/bench_console.py`): a stutter, and the second pose of each burst never seen. The pacer
hands the view the poses in order, one per frame period of wall time, and never lets more than `MAX_BACKLOG`
wait: after a stall or a reconnect it skips to the newest, so pacing adds at most that many frames of delay."""
from __future__ import annotations

import collections
from typing import Protocol

from engine.stream import FramePose

MAX_BACKLOG = 2     # poses waiting behind the one shown; older ones are skipped
EARLY_FRACTION = 0.25  # a pose may be shown this fraction of a frame period early (the refresh tick's granularity)


class RecentPoses(Protocol):
    def recent_poses(self, after: int) -> list[tuple[int, FramePose]]: ...


class PosePacer:
    """The pose to draw now from a synthesizer (`gui.synthesis.SynthesisWorker` or its process twin)."""

    def __init__(self, source: RecentPoses, rate_hz: float) -> None:
        self.source = source
        self.period_s = 1.0 / rate_hz
        self.current: FramePose | None = None
        self._after = 0
        self._waiting: collections.deque[FramePose] = collections.deque()
        self._shown_s = float("-inf")

    def advance(self, now_s: float) -> bool:
        """Take the synthesizer's new poses and move `current` on when the next is due at wall time `now_s`
        (seconds, monotonic). True when `current` changed (the view has a new frame to draw)."""
        new = self.source.recent_poses(self._after)
        if new:
            self._after = new[-1][0]
            self._waiting.extend(pose for _, pose in new)
        while len(self._waiting) > MAX_BACKLOG + 1:
            self._waiting.popleft()
        if not self._waiting or now_s - self._shown_s < (1.0 - EARLY_FRACTION) * self.period_s:
            return False
        self.current = self._waiting.popleft()
        self._shown_s = now_s
        return True

    def reset(self) -> None:
        """Forget the waiting poses and the shown one (a playback seek: the synthesizer starts over)."""
        self._waiting.clear()
        self.current = None
        self._after = max([self._after] + [n for n, _ in self.source.recent_poses(self._after)])
