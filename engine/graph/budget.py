"""Is a graph fast enough to run live? Measured, not guessed: `courtside build-graph` times the online decoder.

The search's cost per sample is O(edges) with a constant that depends on the machine, its load and the graph's
edge layout (runs vs scattered edges, engine/graph/edge_runs.py), so the builder runs the fixed-lag decoder on the
new graph for a short stretch -- its own database motion as input, accelerometers + camera, root warping on, as
a user would run it -- and reports samples per second against the 30 samples/s a live take needs.
"""
from __future__ import annotations

import time

import numpy as np

from .graph import MotionGraph
from engine.mocap.orientation import to_device_earth

from .online import FixedLagSynthesizer
from .orientation_term import node_sensor_orientations
from .root_fusion import RootFusion
from .viterbi import SearchWeights
from .warp import RootWarp

LIVE_RATE_HZ = 30.0


def online_rate(graph: MotionGraph, n_samples: int = 90, lag_s: float = 2.0,
                weights: SearchWeights | None = None, orientations: bool = False) -> tuple[float, float]:
    """Samples per second of `FixedLagSynthesizer` on this graph over `n_samples` pushes (after one warm-up push
    that loads the compiled kernels): (per CPU second -- what the graph costs one core --, per wall second --
    what this machine gave it just now; lower when other processes share the cores). `weights`: the live
    preset (SearchWeights.camera_following) unless given; `orientations`: the database's own sensor orientations
    pushed too (device frames, no yaw offset), so the orientation term runs."""
    nodes = np.arange(n_samples + 1) % graph.n_nodes
    quats = to_device_earth(node_sensor_orientations(graph)[nodes]) if orientations else [None] * len(nodes)
    rows = graph.node_arrival[nodes]
    acc = graph.meta_acc_g[rows].astype(float)
    ground = graph.node_ground_m[np.arange(n_samples + 1) % graph.n_nodes]
    heading = graph.node_heading_rad[np.arange(n_samples + 1) % graph.n_nodes]
    syn = FixedLagSynthesizer(graph, lag_s, weights or SearchWeights.camera_following(), warp=RootWarp(),
                              confidence_reference=1.0, fusion=RootFusion())  # as live: root fusion on
    syn.push(acc[0], ground[0], heading[0], quat_wxyz=quats[0])
    t0, c0 = time.perf_counter(), time.process_time()
    for t in range(1, n_samples + 1):
        syn.push(acc[t], ground[t], heading[t], quat_wxyz=quats[t])
    return n_samples / max(time.process_time() - c0, 1e-9), n_samples / (time.perf_counter() - t0)


def live_verdict(graph: MotionGraph, cpu_rate_hz: float, wall_rate_hz: float) -> str | None:
    """None if the graph runs live, else one line saying why not and what to do."""
    if cpu_rate_hz < LIVE_RATE_HZ:
        return (f"warning: this graph runs online at {cpu_rate_hz:.0f} samples per CPU second, below the "
                f"{LIVE_RATE_HZ:.0f}/s a live take needs ({graph.n_edges} edges; the search costs O(edges) per "
                f"sample): rebuild without --interp, with a lower --threshold, or from fewer clips; offline (batch) "
                f"synthesis is unaffected")
    if wall_rate_hz < LIVE_RATE_HZ:
        return (f"warning: this graph needs {LIVE_RATE_HZ / cpu_rate_hz:.0%} of a core to run live "
                f"({cpu_rate_hz:.0f} samples per CPU second), but this machine gave it only {wall_rate_hz:.0f} "
                f"samples/s just now: other processes share the cores")
    return None
