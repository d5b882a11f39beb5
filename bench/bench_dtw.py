"""Maintained DTW libraries vs the hand-written recursions, on the project's own inputs (CPU time, best of 3,
ratio against the reference measured in the same process).

    python bench/bench_dtw.py
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from engine.graph.interpolate import slope_constrained_dtw  # noqa: E402
from engine.graph.slope_dtw import library_path  # noqa: E402
from engine.hmm.dtw import distance_matrix, dtw, dtw_reference  # noqa: E402
from bench.support.dtw_inputs import hmm_inputs, interpolation_costs  # noqa: E402


def best_of(fn, repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return min(times)


def main() -> None:
    groups, pairs = hmm_inputs()
    costs = interpolation_costs()
    rows = [
        (f"HMM medoid distances ({sum(len(g) * (len(g) - 1) // 2 for g in groups)} pairs)",
         lambda: [[dtw_reference(a, b)[0] for j, b in enumerate(g) if j > i] for g in groups for i, a in enumerate(g)],
         lambda: [distance_matrix(g) for g in groups]),
        (f"HMM registration paths ({len(pairs)} pairs)",
         lambda: [dtw_reference(a, b) for a, b in pairs], lambda: [dtw(a, b) for a, b in pairs]),
        (f"graph interpolation paths ({len(costs)} cost matrices)",
         lambda: [slope_constrained_dtw(c) for c in costs], lambda: [library_path(c) for c in costs]),
    ]
    print(f"{'input':52s} {'reference s':>12s} {'library s':>10s} {'speed-up':>9s}")
    for name, ref, lib in rows:
        t_ref, t_lib = best_of(ref), best_of(lib)
        print(f"{name:52s} {t_ref:12.4f} {t_lib:10.4f} {t_ref / t_lib:8.1f}x")


if __name__ == "__main__":
    main()
