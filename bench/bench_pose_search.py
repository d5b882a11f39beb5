"""Online speed of the forgetting, blended search (issue 11's pose fix) against seed 000's exact Viterbi on the same
graph, in the same process: samples per CPU second of the fixed-lag decoder (lag 2 s, accelerometers + camera +
root warping; and with the orientation term fed the database's own sensor orientations), and the ratio. Live
needs >= 30 samples/s; issue 18 asks >= 100 with the orientation term on the Bandai-1 graph.

    nice -n 10 .venv/bin/python bench/bench_pose_search.py --graph b1.npz [--samples 300] [--repeats 3]
"""
from __future__ import annotations

import argparse
from dataclasses import replace

from engine.graph.budget import LIVE_RATE_HZ, online_rate
from engine.graph.graph import MotionGraph
from engine.graph.viterbi import SearchWeights


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--graph", required=True)
    p.add_argument("--samples", type=int, default=300)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()
    graph = MotionGraph.load(args.graph)
    configs = {"exact Viterbi 0.5/10/3 (before)": (SearchWeights(0.5, 10.0, 3.0), False),
               "forgetting 0.9 + blend 8 (camera_following)": (SearchWeights.camera_following(), False),
               "camera_following + orientations, hinge share only": (
                   replace(SearchWeights.camera_following(), limb_prior_k=0), True),
               "camera_following + orientations (issue 18)": (SearchWeights.camera_following(), True)}
    print(f"graph {args.graph}: {graph.n_nodes} nodes, {graph.n_edges} edges; {args.samples} samples, best of "
          f"{args.repeats}")
    rates = {}
    for name, (weights, orientations) in configs.items():
        rates[name] = max(online_rate(graph, args.samples, 2.0, weights, orientations)[0]
                          for _ in range(args.repeats))
    base = next(iter(rates.values()))
    for name, rate in rates.items():
        print(f"{name:48s} {rate:8.0f} samples per CPU second  x{rate / base:.2f}  "
              f"{'live' if rate >= LIVE_RATE_HZ else 'BELOW LIVE RATE'}")


if __name__ == "__main__":
    main()
