"""OLNG throughput on a >= 500k-frame knowledge base (seed 003, Tautges et al. Table III).

Knowledge base: Bandai Namco datasets 1 + 2 (all clips, 30 Hz) resampled to 25 fps, each clip also
time-reversed ("R"), and each of those performed by three actor sizes (bones x 0.9 / 1.0 / 1.1, Fig. 10b),
readings simulated from every copy. Mirroring ("M") is not possible on Bandai: its rest pose is not
left/right symmetric (engine.mocap.mirror rejects it), so resized actors supply the extra diversity.
One clip (a walk) is held out and streamed through OLNGReconstructor with the paper's K = 4096, I = 256.

Prints per-step ms/frame (kNN search / OLNG update / energy) next to the paper's numbers, and same-run
baselines: brute-force kNN vs the kd-tree, scipy least_squares('trf') vs the default solver.

    .venv/bin/python bench/bench_olng.py [--frames 150] [--scales 0.9 1.0 1.1] [--shared /work/shared/mocap]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core, as the paper's single-threaded MATLAB
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from engine.mocap import load_database, resample  # noqa: E402
from engine.olng.config import EnergyConfig, KnowledgeBaseConfig, OLNGConfig  # noqa: E402
from engine.olng.evaluation import reconstruct, simulate_readings  # noqa: E402
from engine.olng.mocap_bridge import build_knowledge_base  # noqa: E402

PAPER_MS = {"search": 51.0, "graph": 12.0, "optimise": 380.0}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--shared", type=Path, default=Path(os.environ.get("COURTSIDE_MOCAP_DIR", "/work/shared/mocap")))
    ap.add_argument("--frames", type=int, default=150, help="frames of the held-out clip to stream")
    ap.add_argument("--scales", type=float, nargs="+", default=[0.9, 1.0, 1.1])
    ap.add_argument("--baseline-frames", type=int, default=10, help="frames for the slow same-run baselines")
    args = ap.parse_args(argv)
    paths = sorted((args.shared / "bandai-namco-1" / "data").glob("*.bvh")) + sorted((args.shared / "bandai-namco-2" / "data").glob("*.bvh"))
    if not paths:
        print(f"no Bandai BVH files under {args.shared}", file=sys.stderr)
        return 2
    held_out = next(i for i, p in enumerate(paths) if "walk_normal" in p.name)
    t0 = time.perf_counter()
    motions = load_database(paths, fps=25.0)
    t1 = time.perf_counter()
    test = motions.pop(held_out)
    kb = build_knowledge_base(motions, KnowledgeBaseConfig(fps=25.0, reverse=True), scales=tuple(args.scales))
    t2 = time.perf_counter()
    _ = kb.tree
    t3 = time.perf_counter()
    print(f"knowledge base: {len(motions)} Bandai clips x (original + reversed) x scales {args.scales} = {kb.size} frames at 25 fps")
    print(f"load (cached parse) {t1 - t0:.1f} s, build (FK, derivatives, virtual sensors) {t2 - t1:.1f} s, "
          f"kd-tree build {1000 * (t3 - t2):.0f} ms (paper: 1390 ms for N = 6e5)")

    test = resample(test, kb.fps)
    acc = simulate_readings(test, kb, None, np.random.default_rng(0))[: args.frames]
    config = OLNGConfig()
    _, _, rec = reconstruct(kb, config, acc, test.root_positions_m[0], test.rotations[0, 0])
    tm = rec.timings
    per = {"search": tm.search_s, "graph": tm.graph_s, "optimise": tm.optimise_s}
    total_ms = 1000 * sum(per.values()) / tm.frames
    print(f"\nstreamed {tm.frames} frames, K = {config.graph.k_neighbours}, I = {config.graph.i_best}, M = {config.graph.window}, "
          f"mean subspace dims {np.mean(tm.subspace_dims[1:]):.1f}")
    print(f"{'step':<12}{'ms/frame':>10}{'paper ms':>10}{'speed-up':>10}")
    for name, seconds in per.items():
        ms = 1000 * seconds / tm.frames
        print(f"{name:<12}{ms:>10.1f}{PAPER_MS[name]:>10.0f}{PAPER_MS[name] / ms:>9.1f}x")
    print(f"{'total':<12}{total_ms:>10.1f}{sum(PAPER_MS.values()):>10.0f}{sum(PAPER_MS.values()) / total_ms:>9.1f}x"
          f"   -> {1000 / total_ms:.1f} frames/s (target >= 25)")

    # same-run baselines
    queries = acc[: args.baseline_frames].reshape(args.baseline_frames, -1)
    start = time.perf_counter()
    for q in queries:
        d = np.linalg.norm(kb.alpha_g - q, axis=1)
        part = np.argpartition(d, config.graph.k_neighbours)[: config.graph.k_neighbours]
        np.sort(part)
    brute_ms = 1000 * (time.perf_counter() - start) / len(queries)
    print(f"\nbaseline kNN by brute force: {brute_ms:.1f} ms/frame vs kd-tree {1000 * tm.search_s / tm.frames:.1f} ms/frame "
          f"({brute_ms / (1000 * tm.search_s / tm.frames):.1f}x)")
    trf = OLNGConfig(energy=EnergyConfig(solver="trf"))
    _, _, slow = reconstruct(kb, trf, acc[: args.baseline_frames], test.root_positions_m[0], test.rotations[0, 0])
    trf_ms = 1000 * slow.timings.optimise_s / slow.timings.frames
    ours_ms = 1000 * tm.optimise_s / tm.frames
    print(f"baseline energy solver scipy least_squares(trf, max_nfev=30): {trf_ms:.1f} ms/frame vs default {ours_ms:.1f} ms/frame "
          f"({trf_ms / ours_ms:.1f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
