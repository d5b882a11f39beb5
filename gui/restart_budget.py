"""How often a crashed synthesis child may be restarted: a bounded number of restarts within a sliding window.

Why bounded: a child that dies once (killed by the OOM killer, a stray SIGKILL) is worth a restart, since the
operator's view recovers within a second. A child that dies again and again (a corrupt database, an engine bug on
this athlete's data) would fork, load and die in a loop, eating the CPU the other athlete's synthesis needs.
After `max_restarts` within `window_s` the console gives up and says so."""
from __future__ import annotations

import collections
from dataclasses import dataclass, field

MAX_RESTARTS = 3
RESTART_WINDOW_S = 60.0


@dataclass
class RestartBudget:
    """Restart times (monotonic seconds) within the last `window_s`; `take` spends one if any is left."""

    max_restarts: int = MAX_RESTARTS
    window_s: float = RESTART_WINDOW_S
    _times: collections.deque[float] = field(default_factory=collections.deque)

    def take(self, now_s: float) -> bool:
        """Spend a restart at `now_s`: False (nothing spent) when `max_restarts` were spent within `window_s`."""
        while self._times and now_s - self._times[0] >= self.window_s:
            self._times.popleft()
        if len(self._times) >= self.max_restarts:
            return False
        self._times.append(now_s)
        return True

    @property
    def used(self) -> int:
        """Restarts spent within the window as of the last `take`."""
        return len(self._times)
