"""Viterbi search speed and memory (seed 000: 24 s on G_A in 5 s, on G_E (317,600 edges) in 163 s, 2012 CPU).

    .venv/bin/python bench/bench_viterbi.py [--graph big.npz] [--min-edges 300000] [--samples 720]

1. Vectorised search vs a straightforward per-edge Python loop (same costs: eqs. 4/6/7 with position and
   heading) on the small shipped-sample graph, in this process: edges x samples per second and the ratio.
2. A 720-sample (24 s at 30 Hz) sequence on a graph of >= --min-edges edges: `--graph` (e.g. built with
   `courtside build-graph --mocap-dir /work/shared/mocap --pattern 'bandai-namco-*/data/*.bvh' --msv --interp`);
   if it has fewer edges, disjoint copies of it (with perturbed acceleration metadata, so no two copies tie)
   are stacked until it does -- the table says how many. Times: batch with accelerometers only and with
   accelerometers + position + heading; fixed-lag online samples/s; survivor-memory compression and MB.
Every search runs twice in this process: the default numba kernels and the whole-array numpy implementation
(`kernel="numpy"`, kept as the bit-exact reference), and the table says whether their answers are identical.
Times are CPU seconds of this process (time.process_time), so other jobs on the machine inflate them less; the
numba batch searches run --repeats times and the best is reported, with every run's time beside it.
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

from engine.graph.config import GraphConfig
from engine.graph.graph import MotionGraph, build_from_clips
from engine.graph.mocap_adapter import clips_from_motions
from engine.graph.online import FixedLagSynthesizer
from engine.graph.viterbi import Observations, SearchWeights
from engine.graph.search import ViterbiSearch
from engine.mocap import SensorErrorModel, load_database, sample_clips, standard_placements


def reference_loop(g: MotionGraph, obs: Observations, w: SearchWeights) -> float:
    """Plain Python Viterbi (one edge at a time); returns the best final cost."""
    src, dst, meta = g.edge_src.tolist(), g.edge_dst.tolist(), g.edge_meta.tolist()
    acc_meta = g.meta_acc_g.reshape(len(g.meta_acc_g), -1).astype(float).tolist()
    dpos, dh = g.meta_dpos_m.tolist(), g.meta_dheading_rad.tolist()
    n, s = g.n_nodes, g.n_sensors
    m0 = obs.acc_g[0].reshape(-1).tolist()
    arrival = g.node_arrival.tolist()
    G = [w.acc * sum((a - b) ** 2 for a, b in zip(acc_meta[arrival[i]], m0)) / s for i in range(n)]
    P = [tuple(obs.position_m[0])] * n
    O = [float(obs.heading_rad[0])] * n
    for t in range(1, obs.n_samples):
        m = obs.acc_g[t].reshape(-1).tolist()
        mx, mz = obs.position_m[t]
        mh = float(obs.heading_rad[t])
        newG, newP, newO = [math.inf] * n, list(P), list(O)
        for e in range(len(src)):
            a, b, r = src[e], dst[e], meta[e]
            c, sn = math.cos(O[a]), math.sin(O[a])
            px = P[a][0] + dpos[r][0] * c + dpos[r][1] * sn
            pz = P[a][1] - dpos[r][0] * sn + dpos[r][1] * c
            oh = O[a] + dh[r]
            cost = (G[a] + w.acc * sum((x - y) ** 2 for x, y in zip(acc_meta[r], m)) / s
                    + w.position * math.hypot(px - mx, pz - mz)
                    + w.heading * abs((oh - mh + math.pi) % (2 * math.pi) - math.pi))
            if cost < newG[b]:
                newG[b], newP[b], newO[b] = cost, (px, pz), oh
        G, P, O = newG, newP, newO
    return min(G)


def replicate(g: MotionGraph, copies: int, rng: np.random.Generator) -> MotionGraph:
    """`copies` disjoint copies of `g` in one graph (acceleration metadata perturbed by 0.3 g per copy)."""
    n, m = g.n_nodes, len(g.meta_dheading_rad)

    def ids(a, step):
        return np.concatenate([a.astype(np.int64) + i * step for i in range(copies)]).astype(np.int32)

    def tile(a):
        return np.concatenate([a] * copies)
    src, dst = ids(g.edge_src, n), ids(g.edge_dst, n)
    order = np.lexsort((src, dst))
    acc = np.concatenate([g.meta_acc_g + (rng.normal(0, 0.3, g.meta_acc_g.shape) if i else 0)
                          for i in range(copies)]).astype(np.float32)
    return MotionGraph(
        config=g.config, clip_names=g.clip_names, label_names=g.label_names, node_clip=tile(g.node_clip),
        node_clip2=tile(g.node_clip2), node_frame=tile(g.node_frame), node_kind=tile(g.node_kind),
        node_label=tile(g.node_label), node_positions_m=tile(g.node_positions_m),
        node_heading_rad=tile(g.node_heading_rad), node_ground_m=tile(g.node_ground_m),
        node_contacts=tile(g.node_contacts), node_arrival=ids(g.node_arrival, m), edge_src=src[order],
        edge_dst=dst[order], edge_kind=tile(g.edge_kind)[order], edge_meta=ids(g.edge_meta, m)[order],
        meta_acc_g=acc, meta_dheading_rad=tile(g.meta_dheading_rad), meta_dpos_m=tile(g.meta_dpos_m))


def sample_graph_and_take(n_samples: int, rng: np.random.Generator) -> tuple[MotionGraph, Observations]:
    """The shipped CMU graph (MSV) and an input sequence: the clips' own virtual sensors, concatenated and
    repeated to `n_samples`, with the seed-000 sensor error model and 5 cm / 10 deg camera noise."""
    motions = load_database([p for k, p in sample_clips().items() if k.startswith("16_")], fps=30.0)
    cfg = GraphConfig(msv=True)
    clips = clips_from_motions(motions, standard_placements(motions[0].skeleton), cfg)
    g = build_from_clips(clips, cfg)
    acc = np.concatenate([c.acc_g for c in clips])
    ground = np.concatenate([c.ground_m - c.ground_m[0] for c in clips])
    head = np.concatenate([c.heading_rad for c in clips])
    reps = -(-n_samples // len(acc))
    acc, ground, head = (np.concatenate([x] * reps)[:n_samples] for x in (acc, ground, head))
    acc = SensorErrorModel.seed000().apply(acc, 30.0, rng)
    return g, Observations(acc, ground + rng.normal(0, 0.05, ground.shape), head + rng.normal(0, 0.17, len(head)))


def cpu(fn):
    t = time.process_time()
    out = fn()
    return out, time.process_time() - t


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--graph", help="a large graph .npz (default: replicate the shipped-sample graph)")
    p.add_argument("--min-edges", type=int, default=300_000)
    p.add_argument("--samples", type=int, default=720)
    p.add_argument("--lag", type=float, default=2.0)
    p.add_argument("--ref-samples", type=int, default=20)
    p.add_argument("--repeats", type=int, default=3, help="numba batch searches per setting; the best is reported "
                   "(this shared machine's run-to-run noise is +-15 %%)")
    args = p.parse_args()
    rng = np.random.default_rng(0)
    small, obs = sample_graph_and_take(args.samples, rng)
    w = SearchWeights()

    short = Observations(obs.acc_g[: args.ref_samples], obs.position_m[: args.ref_samples],
                         obs.heading_rad[: args.ref_samples])
    _, t_jit = cpu(lambda: ViterbiSearch(small, w).run(short))  # first call: load/compile the numba kernels
    ref_cost, t_ref = cpu(lambda: reference_loop(small, short, w))
    res_np, t_np = cpu(lambda: ViterbiSearch(small, w, kernel="numpy").run(short))
    res, t_vec = cpu(lambda: ViterbiSearch(small, w).run(short))
    work = small.n_edges * (short.n_samples - 1)
    print(f"1. small graph: {small.n_nodes} nodes, {small.n_edges} edges, {short.n_samples} samples "
          f"(acc + position + heading); numba kernels loaded/compiled in {t_jit:.2f} s CPU (not counted)")
    print(f"   per-edge Python loop : {work / t_ref:12.3e} edges*samples/s   (best cost {ref_cost:.4f})")
    print(f"   numpy (reference)    : {work / t_np:12.3e} edges*samples/s   (best cost {res_np.cost:.4f})")
    print(f"   numba (default)      : {work / t_vec:12.3e} edges*samples/s   (best cost {res.cost:.4f})")
    print(f"   speed-up vs loop     : numpy {t_ref / t_np:8.1f} x   numba {t_ref / t_vec:8.1f} x")

    base = MotionGraph.load(args.graph) if args.graph else small
    copies = max(1, -(-args.min_edges // base.n_edges))
    big = replicate(base, copies, rng) if copies > 1 else base
    how = f"{copies} disjoint copies of {'the graph in ' + args.graph if args.graph else 'the sample graph'}"
    print(f"2. large graph: {big.n_nodes} nodes, {big.n_edges} edges ({how}); {obs.n_samples} samples "
          f"= {obs.n_samples / 30:.0f} s at 30 Hz")
    if big.n_sensors != obs.acc_g.shape[1]:
        raise SystemExit("the --graph must have the six seed-000 sensors")
    acc_only = Observations(obs.acc_g, np.r_[obs.position_m[:1], np.full((obs.n_samples - 1, 2), np.nan)],
                            np.r_[obs.heading_rad[:1], np.full(obs.n_samples - 1, np.nan)])
    t = None
    for name, o, weights in (("acc only", acc_only, SearchWeights(0.5, 0, 0)), ("acc+pos+head", obs, w)):
        runs = {"numpy": cpu(lambda: ViterbiSearch(big, weights, kernel="numpy").run(o))}
        repeats = [cpu(lambda: ViterbiSearch(big, weights).run(o)) for _ in range(args.repeats)]
        runs["numba"] = min(repeats, key=lambda rt: rt[1])
        spread = f"  (best of {len(repeats)}: {', '.join(f'{tk:.2f}' for _, tk in repeats)})" if len(repeats) > 1 else ""
        for kernel, (r, tk) in runs.items():
            print(f"   batch {name:13s} {kernel:5s}: {tk:7.2f} s CPU  {big.n_edges * (o.n_samples - 1) / tk:10.3e} "
                  f"edges*samples/s  compression {r.compression_ratio:7.1f}:1  lattice "
                  f"{r.lattice_entries * 4 / 1e6:7.2f} MB (uncompressed {big.n_nodes * (o.n_samples - 1) * 4 / 1e6:.0f} MB)"
                  + (spread if kernel == "numba" else ""))
        (ra, ta), (rb, tb) = runs["numpy"], runs["numba"]
        identical = (np.array_equal(ra.nodes, rb.nodes) and np.array_equal(ra.edges, rb.edges) and ra.cost == rb.cost
                     and np.array_equal(ra.ground_m, rb.ground_m))
        print(f"   batch {name:13s} numba vs numpy: {ta / tb:5.2f} x faster; path, cost and track "
              f"{'bit-identical' if identical else 'DIFFER'}")
        t = tb
    for kernel in ("numpy", "numba"):
        syn = FixedLagSynthesizer(big, args.lag, w, kernel=kernel)

        def online():
            for i in range(obs.n_samples):
                syn.push(obs.acc_g[i], obs.position_m[i], obs.heading_rad[i])
            syn.flush()
        _, t_on = cpu(online)
        print(f"   fixed-lag online (lag {args.lag:g} s) {kernel:5s}: {obs.n_samples / t_on:7.1f} samples/s "
              f"({t_on / obs.n_samples * 1000:.1f} ms per sample)")
    a, b = np.ones(big.n_edges), np.ones(big.n_edges)
    _, t_pass = cpu(lambda: [np.add(a, b, out=a) for _ in range(200)])
    print(f"   machine reference: one float64 add over {big.n_edges} elements = {t_pass / 200 * 1e3:.2f} ms CPU; "
          f"a numba search step (acc+pos+head) costs about {t / obs.n_samples / (t_pass / 200):.0f} such passes")


if __name__ == "__main__":
    main()
