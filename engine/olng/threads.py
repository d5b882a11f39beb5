"""One BLAS thread around a per-frame engine step.

WHY: the live engines do many tiny linear-algebra calls per frame (OLNG: a ~93 x 93 `eigh` for the weighted PCA,
small solves; the HMM: small matrix products). OpenBLAS splits even these across all cores; on a 2-core machine
that also runs the console (and, under load, other processes) the threads wait for each other and one 93 x 93
float32 `eigh` took 10 ms with 2 threads against 0.65 ms with one (measured, docs/engine-olng-hmm.md). That was
most of why live OLNG cost 41-68 ms/frame while the offline bench (which sets OPENBLAS_NUM_THREADS=1) said 18.9.
The limit is scoped to each step (threadpoolctl, ~15 us to set and restore), so the rest of the process keeps
its threads. Without threadpoolctl (a core install without the engine extra) steps run unlimited.
"""
from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import ContextManager

try:
    from threadpoolctl import ThreadpoolController
except ImportError:  # core install: the engine extra brings threadpoolctl
    ThreadpoolController = None  # type: ignore[assignment,misc]


def single_blas_thread() -> Callable[[], ContextManager]:
    """A factory of context managers that hold BLAS to one thread. Call it after numpy/scipy are imported (the
    controller sees the BLAS libraries loaded at that time) and reuse the factory every frame."""
    if ThreadpoolController is None:
        return contextlib.nullcontext
    controller = ThreadpoolController()
    return lambda: controller.limit(limits=1, user_api="blas")
