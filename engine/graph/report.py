"""What a motion graph can do, in numbers a user can check before a take (issue 11's graph report).

* size: nodes, edges, database frames, clips;
* strongly connected components (SCC): a long take can only be followed forever inside one; the share of the
  largest (of all nodes and of database frames) says how much of the database a long take can really use;
* dead ends (no outgoing edge) and nodes that cannot reach the largest SCC (a path entering them must end);
* clips with a frame in the largest SCC, and clips reachable from it;
* the range of turn rates (deg/s) and ground speeds (m/s) the database's clips cover over 1 s windows; with
  motion speed variations the speed-up edges play a clip at twice its speed, so the graph covers up to twice
  that (where both feet are not off the ground).

`coverage_warning` compares a camera track with those ranges: a take that turns or runs faster than any clip
cannot be followed by a path through the graph, whatever the weights.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components

from .graph import MotionGraph
from .parts import EDGE_SPEEDUP, NODE_ORIGINAL

WINDOW_S = 1.0  # turn rates and speeds are measured over this window (the "in any 1 s")
TRACK_WINDOW_S = 2.0  # the camera track's rates are least-squares slopes over this window: with 10 deg of
# heading noise per fix at 30 Hz the slope's sd is 6.3 deg/s over 1 s but 2.2 deg/s over 2 s
TRACK_QUANTILE = 0.9  # the camera track's rate that must be covered (robust to camera noise)


PERCENTILES = (50, 95, 99, 100)
COVERED = 2  # index into PERCENTILES: the graph "covers" up to its clips' 99th percentile (a single spinning
# dance clip reaches 391 deg/s on Bandai dataset 1; that does not make the graph able to follow a turning walk)


@dataclass(frozen=True)
class MotionRange:
    """Turn rates (deg/s) and speeds (m/s) over 1 s windows of the database clips at PERCENTILES."""

    turn_deg_s: tuple[float, ...]
    speed_mps: tuple[float, ...]
    speedup: float  # factor the graph's speed-up edges add (2 with MSV, else 1)

    @property
    def max_turn_deg_s(self) -> float:
        """The turn rate the graph covers (99th percentile of its clips, times the speed-up factor)."""
        return self.turn_deg_s[COVERED] * self.speedup

    @property
    def max_speed_mps(self) -> float:
        return self.speed_mps[COVERED] * self.speedup


@dataclass(frozen=True)
class GraphReport:
    nodes: int
    edges: int
    frames: int  # database frames (original nodes)
    clips: int
    components: int  # strongly connected components
    largest_nodes: int
    largest_frames: int
    dead_ends: int  # nodes without an outgoing edge
    cannot_reach_largest: int  # nodes with no path into the largest component
    clips_in_largest: int
    clips_reachable: int  # clips with a node reachable from the largest component
    motion: MotionRange

    @property
    def largest_node_share(self) -> float:
        return self.largest_nodes / max(self.nodes, 1)

    @property
    def largest_frame_share(self) -> float:
        return self.largest_frames / max(self.frames, 1)


def _adjacency(graph: MotionGraph) -> csr_matrix:
    n = graph.n_nodes
    return csr_matrix((np.ones(graph.n_edges, np.int8), (graph.edge_src, graph.edge_dst)), shape=(n, n))


def _window_rates(heading_rad: np.ndarray, ground_m: np.ndarray, frames: int, window_s: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """|heading change| (deg/s) and ground speed (m/s) over every `frames`-frame window of one clip."""
    if len(heading_rad) <= frames:
        return np.zeros(0), np.zeros(0)
    h = np.unwrap(heading_rad)
    turn = np.degrees(np.abs(h[frames:] - h[:-frames])) / window_s
    speed = np.linalg.norm(ground_m[frames:] - ground_m[:-frames], axis=1) / window_s
    return turn, speed


def motion_range(graph: MotionGraph, window_s: float = WINDOW_S) -> MotionRange:
    """Turn rates and speeds of the database clips (their original frames, in clip order)."""
    orig = np.flatnonzero(graph.node_kind == NODE_ORIGINAL)
    order = orig[np.lexsort((graph.node_frame[orig], graph.node_clip[orig]))]
    clip = graph.node_clip[order]
    frames = max(1, int(round(window_s * graph.config.fps)))
    turns, speeds = [np.zeros(0)], [np.zeros(0)]
    for part in np.split(order, np.flatnonzero(np.diff(clip)) + 1):
        t, s = _window_rates(graph.node_heading_rad[part], graph.node_ground_m[part], frames, window_s)
        turns.append(t)
        speeds.append(s)
    turn, speed = np.concatenate(turns), np.concatenate(speeds)
    stats = (lambda v: tuple(float(x) for x in np.percentile(v, PERCENTILES)) if len(v) else (0.0,) * len(PERCENTILES))
    speedup = 2.0 if np.any(graph.edge_kind == EDGE_SPEEDUP) else 1.0
    return MotionRange(stats(turn), stats(speed), speedup)


def graph_report(graph: MotionGraph, window_s: float = WINDOW_S) -> GraphReport:
    adj = _adjacency(graph)
    n_comp, comp = connected_components(adj, directed=True, connection="strong")
    sizes = np.bincount(comp, minlength=n_comp)
    largest = int(np.argmax(sizes)) if graph.n_nodes else 0
    in_largest = comp == largest
    original = graph.node_kind == NODE_ORIGINAL
    seed = int(np.flatnonzero(in_largest)[0]) if graph.n_nodes else 0
    reach = breadth_first_order(adj, seed, directed=True, return_predecessors=False)
    back = breadth_first_order(adj.T.tocsr(), seed, directed=True, return_predecessors=False)
    out_degree = np.bincount(graph.edge_src, minlength=graph.n_nodes)
    return GraphReport(
        nodes=graph.n_nodes, edges=graph.n_edges, frames=int(original.sum()), clips=len(graph.clip_names),
        components=int(n_comp), largest_nodes=int(sizes[largest]) if graph.n_nodes else 0,
        largest_frames=int((in_largest & original).sum()), dead_ends=int((out_degree == 0).sum()),
        cannot_reach_largest=int(graph.n_nodes - len(back)),
        clips_in_largest=int(len(np.unique(graph.node_clip[in_largest]))),
        clips_reachable=int(len(np.unique(graph.node_clip[reach]))), motion=motion_range(graph, window_s))


def format_report(r: GraphReport) -> str:
    m = r.motion
    return "\n".join([
        f"graph: {r.nodes} nodes, {r.edges} edges, {r.frames} database frames from {r.clips} clips",
        f"strongly connected components: {r.components}; the largest holds {r.largest_nodes} nodes "
        f"({100 * r.largest_node_share:.1f} %) and {r.largest_frames} database frames "
        f"({100 * r.largest_frame_share:.1f} %), from {r.clips_in_largest} of {r.clips} clips",
        f"dead ends (no outgoing edge): {r.dead_ends} nodes; cannot reach the largest component: "
        f"{r.cannot_reach_largest} nodes; clips reachable from it: {r.clips_reachable}",
        "clips' turn rate over 1 s (median / 95 % / 99 % / max): "
        + " / ".join(f"{v:.0f}" for v in m.turn_deg_s) + " deg/s; speed: "
        + " / ".join(f"{v:.2f}" for v in m.speed_mps) + " m/s",
        f"covered (99 %{f' x{m.speedup:g} with speed-up edges' if m.speedup != 1 else ''}): turns up to "
        f"{m.max_turn_deg_s:.0f} deg/s, speeds up to {m.max_speed_mps:.2f} m/s",
    ])


def _sliding_slopes(t_s: np.ndarray, y: np.ndarray, ok: np.ndarray, frames: int) -> np.ndarray:
    """Least-squares slope of y over t in every window of `frames` samples (only `ok` samples count);
    windows with fewer than 3 valid samples give NaN."""
    def window_sums(v: np.ndarray) -> np.ndarray:
        c = np.r_[0.0, np.cumsum(np.where(ok, v, 0.0))]
        return c[frames:] - c[:-frames]
    n = window_sums(np.ones_like(t_s))
    st, sy, stt, sty = (window_sums(v) for v in (t_s, y, t_s * t_s, t_s * y))
    den = n * stt - st * st
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (n * sty - st * sy) / den
    return np.where((n >= 3) & (den > 0), slope, np.nan)


def track_rates(position_m: np.ndarray | None, heading_rad: np.ndarray | None, fps: float,
                window_s: float = WINDOW_S) -> tuple[np.ndarray, np.ndarray]:
    """|turn rate| (deg/s) and speed (m/s) of a camera track per sliding window (least-squares fits, so the
    camera's per-fix noise averages out); NaN samples are gaps."""
    frames = max(3, int(round(window_s * fps)))
    t = np.arange(0 if heading_rad is None else len(heading_rad)) / fps
    turn = speed = np.zeros(0)
    if heading_rad is not None and len(heading_rad) >= frames:
        ok = np.isfinite(heading_rad)
        h = np.zeros(len(heading_rad))
        h[ok] = np.unwrap(heading_rad[ok])
        turn = np.degrees(np.abs(_sliding_slopes(t, h, ok, frames)))
    if position_m is not None and len(position_m) >= frames:
        t = np.arange(len(position_m)) / fps
        ok = np.all(np.isfinite(position_m), axis=1)
        p = np.where(ok[:, None], position_m, 0.0)
        speed = np.hypot(_sliding_slopes(t, p[:, 0], ok, frames), _sliding_slopes(t, p[:, 1], ok, frames))
    return turn, speed


def coverage_warning(motion: MotionRange, position_m: np.ndarray | None, heading_rad: np.ndarray | None,
                     fps: float, window_s: float = TRACK_WINDOW_S, quantile: float = TRACK_QUANTILE) -> str | None:
    """One line if the camera track asks for turn rates or speeds beyond what the graph covers, else None.
    The track's rate is its `quantile` over sliding windows (a few noisy windows do not warn); the graph's is
    its clips' fastest 1 s window (times the speed-up factor)."""
    turn, speed = track_rates(position_m, heading_rad, fps, window_s)
    asks = []
    for name, values, limit, unit in (("turns at", turn, motion.max_turn_deg_s, "deg/s"),
                                      ("moves at", speed, motion.max_speed_mps, "m/s")):
        values = values[np.isfinite(values)]
        if len(values) and np.quantile(values, quantile) > limit:
            fmt = ".0f" if unit == "deg/s" else ".2f"
            asks.append(f"{name} {np.quantile(values, quantile):{fmt}} {unit} ({100 * quantile:.0f}th percentile "
                        f"over {window_s:g} s; the graph covers up to {limit:{fmt}} {unit})")
    if not asks:
        return None
    return ("warning: the camera track " + " and ".join(asks)
            + ": the graph has no motion that fast; expect the root to lag the camera")
