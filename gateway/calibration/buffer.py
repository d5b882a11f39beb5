"""Growable per-sensor sample buffer (times s, accelerations g) with amortised O(1) appends and drops.

Why not Python lists: the wizard slices time windows on every evaluation; contiguous numpy arrays make that a
``searchsorted`` and a view. Old samples are dropped by advancing a start index and compacting only when
the dead prefix is large, so a push never copies the whole buffer."""
from __future__ import annotations

import numpy as np


class SampleBuffer:
    """Samples in arrival order (times must not decrease; older-than-last samples are dropped and counted)."""

    def __init__(self, capacity: int = 256) -> None:
        self._t = np.empty(capacity)
        self._acc = np.empty((capacity, 3))
        self._start = 0
        self._n = 0  # end index (exclusive)
        self.out_of_order = 0

    def __len__(self) -> int:
        return self._n - self._start

    @property
    def t_s(self) -> np.ndarray:
        return self._t[self._start : self._n]

    @property
    def acc_g(self) -> np.ndarray:
        return self._acc[self._start : self._n]

    @property
    def last_t_s(self) -> float:
        return float(self._t[self._n - 1]) if self._n > self._start else -np.inf

    def extend(self, t_s: np.ndarray, acc_g: np.ndarray) -> None:
        t = np.atleast_1d(np.asarray(t_s, float))
        acc = np.asarray(acc_g, float).reshape(-1, 3)
        if len(t) != len(acc):
            raise ValueError(f"{len(t)} timestamps but {len(acc)} samples")
        keep = t >= np.maximum.accumulate(np.concatenate([[self.last_t_s], t]))[:-1]
        if not keep.all():
            self.out_of_order += int((~keep).sum())
            t, acc = t[keep], acc[keep]
        need = self._n + len(t)
        if need > len(self._t):
            live = self._n - self._start
            if self._start and live + len(t) <= len(self._t) // 2:  # compact in place
                self._t[:live] = self._t[self._start : self._n]
                self._acc[:live] = self._acc[self._start : self._n]
            else:  # grow (and compact)
                size = max(2 * len(self._t), 2 * (live + len(t)))
                new_t, new_acc = np.empty(size), np.empty((size, 3))
                new_t[:live], new_acc[:live] = self._t[self._start : self._n], self._acc[self._start : self._n]
                self._t, self._acc = new_t, new_acc
            self._start, self._n = 0, live
            need = live + len(t)
        self._t[self._n : need] = t
        self._acc[self._n : need] = acc
        self._n = need

    def window(self, t0_s: float, t1_s: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
        """Views of the samples with ``t0_s <= t <= t1_s``."""
        t = self.t_s
        i0 = self._start + int(np.searchsorted(t, t0_s, side="left"))
        i1 = self._start + int(np.searchsorted(t, t1_s, side="right"))
        return self._t[i0:i1], self._acc[i0:i1]

    def drop_before(self, t0_s: float) -> None:
        """Forget samples older than ``t0_s`` (keeps the live buffer bounded)."""
        self._start += int(np.searchsorted(self.t_s, t0_s, side="left"))
