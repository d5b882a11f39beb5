"""Growable per-sensor sample buffer (times s, accelerations g and, for a sensor that streams it, its orientation
quaternion) with amortised O(1) appends and drops.

Why not Python lists: the wizard slices time windows on every evaluation; contiguous numpy arrays make that a
``searchsorted`` and a view. Old samples are dropped by advancing a start index and compacting only when
the dead prefix is large, so a push never copies the whole buffer. Accelerations and quaternions share one
(capacity, 7) array so they stay aligned sample for sample; a sample without an orientation holds NaN there."""
from __future__ import annotations

import numpy as np

_ACC, _QUAT = slice(0, 3), slice(3, 7)


class SampleBuffer:
    """Samples in arrival order (times must not decrease; older-than-last samples are dropped and counted)."""

    def __init__(self, capacity: int = 256) -> None:
        self._t = np.empty(capacity)
        self._values = np.empty((capacity, 7))
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
        return self._values[self._start : self._n, _ACC]

    @property
    def last_t_s(self) -> float:
        return float(self._t[self._n - 1]) if self._n > self._start else -np.inf

    def extend(self, t_s: np.ndarray, acc_g: np.ndarray, quat_wxyz: np.ndarray | None = None) -> None:
        """Append samples: times (N,), accelerations (N, 3) and optionally orientations (N, 4) (NaN rows: none)."""
        t = np.atleast_1d(np.asarray(t_s, float))
        values = np.full((len(t), 7), np.nan)
        acc = np.asarray(acc_g, float).reshape(-1, 3)
        if len(acc) != len(t):
            raise ValueError(f"{len(t)} timestamps but {len(acc)} samples")
        values[:, _ACC] = acc
        if quat_wxyz is not None:
            quat = np.asarray(quat_wxyz, float).reshape(-1, 4)
            if len(quat) != len(t):
                raise ValueError(f"{len(t)} timestamps but {len(quat)} orientations")
            values[:, _QUAT] = quat
        keep = t >= np.maximum.accumulate(np.concatenate([[self.last_t_s], t]))[:-1]
        if not keep.all():
            self.out_of_order += int((~keep).sum())
            t, values = t[keep], values[keep]
        need = self._n + len(t)
        if need > len(self._t):
            live = self._n - self._start
            if self._start and live + len(t) <= len(self._t) // 2:  # compact in place
                self._t[:live] = self._t[self._start : self._n]
                self._values[:live] = self._values[self._start : self._n]
            else:  # grow (and compact)
                size = max(2 * len(self._t), 2 * (live + len(t)))
                new_t, new_values = np.empty(size), np.empty((size, 7))
                new_t[:live], new_values[:live] = self._t[self._start : self._n], self._values[self._start : self._n]
                self._t, self._values = new_t, new_values
            self._start, self._n = 0, live
            need = live + len(t)
        self._t[self._n : need] = t
        self._values[self._n : need] = values
        self._n = need

    def _range(self, t0_s: float, t1_s: float) -> slice:
        t = self.t_s
        i0 = self._start + int(np.searchsorted(t, t0_s, side="left"))
        i1 = self._start + int(np.searchsorted(t, t1_s, side="right"))
        return slice(i0, i1)

    def window(self, t0_s: float, t1_s: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
        """Views of the times and accelerations with ``t0_s <= t <= t1_s``."""
        span = self._range(t0_s, t1_s)
        return self._t[span], self._values[span, _ACC]

    def quat_window(self, t0_s: float, t1_s: float = np.inf) -> np.ndarray:
        """View of the orientations (N, 4) of the same samples as `window` (NaN rows: none streamed)."""
        return self._values[self._range(t0_s, t1_s), _QUAT]

    def drop_before(self, t0_s: float) -> None:
        """Forget samples older than ``t0_s`` (keeps the live buffer bounded)."""
        self._start += int(np.searchsorted(self.t_s, t0_s, side="left"))
