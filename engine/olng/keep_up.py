"""Keep a live engine at least 2x faster than real time by stepping its effort down (and back up), and say so.

WHY: the console must never fall behind the stream (issue 21). OLNG's cost per frame depends on the machine and
its load (the same step costs 13 ms on a quiet core and several times that on a busy 2-core box). Instead of
queueing frames, a live engine measures its own wall time per frame and, when the recent mean exceeds its budget
(``headroom`` x the frame period: 0.5 = 2x real time), moves to the next cheaper level (fewer neighbours, fewer
hypotheses, and below those fewer optimiser iterations: the energy is most of a frame's cost at small K); when the mean falls below a third of the budget it moves one level back up (the gap between the two
thresholds keeps it from flapping, since one level roughly halves the cost). `status` is one line for the
console's status bar. Offline runs do not use this: their results must not depend on the machine.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass


@dataclass(frozen=True)
class Effort:
    """One level of an engine's per-frame effort (OLNG: neighbours K, hypotheses I, energy iterations)."""

    k_neighbours: int
    i_best: int
    iterations: int

    def label(self) -> str:
        return f"K {self.k_neighbours} / I {self.i_best} / {self.iterations} it"


FLOOR = Effort(256, 16, 1)


def effort_levels(start: Effort, floor: Effort = FLOOR) -> list[Effort]:
    """``start``, then halvings of K and I down to ``floor``, then fewer energy iterations (5 -> 2 -> 1 by
    halvings): never below the floor, never above the start. Iterations go last because they cost least
    accuracy per ms saved only once K and I are small (shipped-clip leave-one-out at K 256 / I 16, joint cm:
    5 / 2 / 1 iterations 4.25 / 4.33 / 4.49, with orientations 3.83 / 3.85 / 3.98; docs/engine-olng-hmm.md)."""
    def cheaper(value: int, least: int, first: int) -> int:
        return max(value // 2, min(least, first))

    levels = [start]
    while True:
        last = levels[-1]
        if last.k_neighbours > floor.k_neighbours or last.i_best > floor.i_best:
            nxt = Effort(cheaper(last.k_neighbours, floor.k_neighbours, start.k_neighbours),
                         cheaper(last.i_best, floor.i_best, start.i_best), last.iterations)
        elif last.iterations > floor.iterations:
            nxt = Effort(last.k_neighbours, last.i_best, cheaper(last.iterations, floor.iterations, start.iterations))
        else:
            return levels
        levels.append(nxt)


class KeepUp:
    """Chooses the effort level from measured wall time per frame (module doc)."""

    def __init__(self, levels: list[Effort], frame_period_s: float, headroom: float = 0.5, window: int = 50) -> None:
        if not levels:
            raise ValueError("KeepUp needs at least one effort level")
        self.levels = levels
        self.budget_s = headroom * frame_period_s
        self.level = 0
        self._times: deque[float] = deque(maxlen=window)
        self._last_mean_s = 0.0   # the mean wall time per frame that made the last change

    @property
    def effort(self) -> Effort:
        return self.levels[self.level]

    def record(self, seconds: float) -> bool:
        """One frame's wall time; True when the level changed (the caller applies `effort`). Decides on a full
        window of frames measured at the current level -- or, when frames cost more than twice the budget, after a
        fifth of one, dropping as many levels as halvings it needs: on a slow machine the first level can cost 4x
        its budget, and a full window of such frames puts the stream seconds behind before the first step."""
        self._times.append(seconds)
        n = len(self._times)
        mean = sum(self._times) / n
        early = n >= max(1, self._times.maxlen // 5) and mean > 2 * self.budget_s
        if n < self._times.maxlen and not early:
            return False
        if mean > self.budget_s and self.level + 1 < len(self.levels):
            step = min(len(self.levels) - 1 - self.level, max(1, math.ceil(math.log2(mean / self.budget_s))))
        elif mean < self.budget_s / 3 and self.level > 0:
            step = -1
        else:
            return False
        self.level += step
        self._last_mean_s = mean
        self._times.clear()
        return True

    @property
    def status(self) -> str:
        """"" at full effort, else what was given up and why (one status-bar line)."""
        if self.level == 0:
            return ""
        return (f"cheaper setting to keep up: {self.effort.label()} instead of {self.levels[0].label()} "
                f"(changed at {1e3 * self._last_mean_s:.0f} ms/frame; budget {1e3 * self.budget_s:.0f} ms)")
