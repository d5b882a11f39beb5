"""Viterbi search over a motion graph (seed 000 sections 5-5.4), as whole-array numpy operations.

Per input sample every path is extended by one edge: G(n,t) = min over edges e=(m->n) of L(e,t) + G(m,t-1), with
L = W_A C_A + W_P C_P + W_O C_O (eqs. 4, 6, 7). The minimum over incoming edges is one `np.minimum.reduceat`
over the dst-sorted edge array. C_A is computed per metadata row with one GEMV (||E||^2 precomputed, the
square expanded) and gathered per edge. Each path carries its own global ground position and heading
(eq. 5), so the position and heading costs are per edge; they are evaluated in each source node's local frame
(||P + R(O) d - M|| = ||R(-O)(P - M) + d||), which moves the rotation from the E edges to the N nodes.

Human constraints (eq. 8) add a count of broken requirements G_r, compared before G: only incoming edges whose
source has the fewest broken constraints compete.

Back-pointers are int32 edge indices, one column per sample; survivor-path memory reduction (Abbasfar & Yao)
periodically back-traces from every live node and keeps, per column, only the entries some survivor uses.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import TWO_PI, rotate_ground, wrap_angle
from .graph import MotionGraph


@dataclass(frozen=True)
class SearchWeights:
    """Weights of eq. 6 (cost units: g^2, metres, radians). Paper's best tennis setting: 0.5 / 1 / 1."""

    acc: float = 0.5
    position: float = 1.0
    heading: float = 1.0


@dataclass(frozen=True)
class Constraint:
    """A human requirement (eq. 8): during frames [frame - tolerance, frame + tolerance] the path must be on a
    node where `node_mask` is True; every sample spent elsewhere counts one broken constraint."""

    frame: int
    tolerance_frames: int
    node_mask: np.ndarray  # (N,) bool


@dataclass
class Observations:
    """A synchronised input sequence at the graph rate. Missing position/heading samples are NaN (the term is
    skipped for that sample); `sensor_indices` picks the graph sensors the acc columns correspond to."""

    acc_g: np.ndarray | None  # (T, S', 3)
    position_m: np.ndarray | None = None  # (T, 2) ground (x, z)
    heading_rad: np.ndarray | None = None  # (T,)
    sensor_indices: tuple[int, ...] | None = None

    @property
    def n_samples(self) -> int:
        for arr in (self.acc_g, self.position_m, self.heading_rad):
            if arr is not None:
                return int(len(arr))
        raise ValueError("observations hold no data")


@dataclass
class SearchResult:
    """The chosen path: node per sample, the edge that reached it (-1 for the first sample), and the path's
    global ground position (m) and heading (rad) per sample, as the search tracked them."""

    nodes: np.ndarray  # (T,) int64
    edges: np.ndarray  # (T,) int64
    ground_m: np.ndarray  # (T, 2)
    heading_rad: np.ndarray  # (T,)
    cost: float
    broken_constraints: int
    compression_ratio: float
    lattice_entries: int


@dataclass
class _Column:
    """Back-pointers of one sample: `edges[i]` reached `nodes[i]`; nodes None = aligned with the graph's
    segment nodes (a full column not yet pruned)."""

    nodes: np.ndarray | None
    edges: np.ndarray  # int32


class ViterbiLattice:
    """The running search state; `ViterbiSearch` (batch) and `FixedLagSynthesizer` (online) both drive it,
    so the two give identical paths when the lag covers the whole sequence."""

    def __init__(self, graph: MotionGraph, weights: SearchWeights = SearchWeights(),
                 sensor_indices: tuple[int, ...] | None = None, prune_every: int = 32) -> None:
        self.graph = graph
        self.weights = weights
        self.prune_every = prune_every
        sel = list(range(graph.n_sensors)) if sensor_indices is None else list(sensor_indices)
        self.n_sensors = len(sel)
        e = np.ascontiguousarray(graph.meta_acc_g[:, sel, :].reshape(len(graph.meta_acc_g), -1), dtype=np.float64)
        self._meta_acc = e
        self._meta_acc_sq = np.einsum("ij,ij->i", e, e)
        self._src = graph.edge_src.astype(np.intp)
        self._meta = graph.edge_meta.astype(np.intp)
        self._dpx = graph.meta_dpos_m[self._meta, 0].copy()
        self._dpz = graph.meta_dpos_m[self._meta, 1].copy()
        self._dh = graph.meta_dheading_rad[self._meta].copy()
        self.seg_nodes, self.seg_starts = graph.segments()
        self._seg_of_edge = np.repeat(np.arange(len(self.seg_starts)), np.diff(np.r_[self.seg_starts, graph.n_edges]))
        self._seg_pos = np.full(graph.n_nodes, -1, dtype=np.int64)
        self._seg_pos[self.seg_nodes] = np.arange(len(self.seg_nodes))
        self._edge_ids = np.arange(graph.n_edges)
        self.columns: list[_Column] = []
        self.t = -1  # index of the last sample consumed
        self.first_column_time = 1  # time of columns[0]
        self._since_prune = 0

    # ----- costs --------------------------------------------------------------------------------
    def _acc_rows(self, acc_g: np.ndarray | None) -> np.ndarray | None:
        """C_A for every metadata row (eq. 4), one GEMV with the square expanded."""
        if acc_g is None or self.n_sensors == 0 or self.weights.acc == 0:
            return None
        m = np.asarray(acc_g, dtype=np.float64).reshape(-1)
        if m.size != self._meta_acc.shape[1]:
            raise ValueError(f"expected {self.n_sensors} sensors x 3 axes, got shape {np.shape(acc_g)}")
        return (self._meta_acc_sq - 2.0 * (self._meta_acc @ m) + m @ m) * (self.weights.acc / self.n_sensors)

    # ----- stepping -----------------------------------------------------------------------------
    def start(self, acc_g: np.ndarray | None, position_m: np.ndarray | None, heading_rad: float | None,
              penalty: np.ndarray | None = None) -> None:
        """First sample: every node may start a path; its cost is the arrival row's C_A, global state = input."""
        n = self.graph.n_nodes
        rows = self._acc_rows(acc_g)
        self.G = np.zeros(n) if rows is None else rows[self.graph.node_arrival]
        pos = np.zeros(2) if position_m is None or np.any(np.isnan(position_m)) else np.asarray(position_m, float)
        head = 0.0 if heading_rad is None or np.isnan(heading_rad) else float(heading_rad)
        self.P = np.tile(pos, (n, 1))
        self.O = np.full(n, head)
        self.Gr = np.zeros(n) if penalty is None else penalty.astype(float)
        self.constrained = penalty is not None
        self.t = 0

    def step(self, acc_g: np.ndarray | None, position_m: np.ndarray | None, heading_rad: float | None,
             penalty: np.ndarray | None = None) -> None:
        """Advance every path by one edge for the next sample (O(E) array work)."""
        if self.t < 0:
            self.start(acc_g, position_m, heading_rad, penalty)
            return
        src = self._src
        cost = self.G[src]
        rows = self._acc_rows(acc_g)
        if rows is not None:
            cost += rows[self._meta]
        if position_m is not None and not np.any(np.isnan(position_m)) and self.weights.position != 0:
            d = self.P - np.asarray(position_m, float)
            c, s = np.cos(self.O), np.sin(self.O)
            ux = d[:, 0] * c - d[:, 1] * s
            uz = d[:, 0] * s + d[:, 1] * c
            ex = ux[src]
            ex += self._dpx
            ez = uz[src]
            ez += self._dpz
            np.multiply(ex, ex, out=ex)
            np.multiply(ez, ez, out=ez)
            ex += ez
            np.sqrt(ex, out=ex)
            ex *= self.weights.position
            cost += ex
        if heading_rad is not None and not np.isnan(heading_rad) and self.weights.heading != 0:
            hd = wrap_angle(self.O - heading_rad)
            x = hd[src]
            x += self._dh
            np.abs(x, out=x)
            np.minimum(x, TWO_PI - x, out=x)
            x *= self.weights.heading
            cost += x
        self.constrained |= penalty is not None
        if self.constrained:
            gr_e = self.Gr[src]
            gr_min = np.minimum.reduceat(gr_e, self.seg_starts)
            cost[gr_e > gr_min[self._seg_of_edge]] = np.inf
        seg_min = np.minimum.reduceat(cost, self.seg_starts)
        is_min = cost == seg_min[self._seg_of_edge]
        win = np.minimum.reduceat(np.where(is_min, self._edge_ids, self.graph.n_edges), self.seg_starts)
        wsrc = src[win]
        n = self.graph.n_nodes
        G = np.full(n, np.inf)
        G[self.seg_nodes] = seg_min
        newO = self.O.copy()
        newP = self.P.copy()
        o = self.O[wsrc]
        c, s = np.cos(o), np.sin(o)
        dx, dz = self._dpx[win], self._dpz[win]
        newP[self.seg_nodes, 0] = self.P[wsrc, 0] + dx * c + dz * s
        newP[self.seg_nodes, 1] = self.P[wsrc, 1] - dx * s + dz * c
        newO[self.seg_nodes] = wrap_angle(o + self._dh[win])
        Gr = self.Gr
        if self.constrained:
            Gr = np.full(n, np.inf)
            Gr[self.seg_nodes] = self.Gr[wsrc]
            if penalty is not None:
                Gr += penalty
            Gr[~np.isfinite(G)] = np.inf
        self.G, self.P, self.O, self.Gr = G, newP, newO, Gr
        self.columns.append(_Column(None, win.astype(np.int32)))
        self.t += 1
        self._since_prune += 1
        if self.prune_every and self._since_prune >= self.prune_every:
            self.prune()

    # ----- path memory --------------------------------------------------------------------------
    def _lookup(self, col: _Column, nodes: np.ndarray) -> np.ndarray:
        idx = self._seg_pos[nodes] if col.nodes is None else np.searchsorted(col.nodes, nodes)
        return col.edges[idx].astype(np.intp)

    def prune(self) -> None:
        """Survivor-path memory reduction: keep only lattice entries on some live node's back-trace."""
        self._since_prune = 0
        alive = np.flatnonzero(np.isfinite(self.G))
        for k in range(len(self.columns) - 1, -1, -1):
            col = self.columns[k]
            if col.nodes is not None and len(col.nodes) == len(alive) and np.array_equal(col.nodes, alive):
                break  # earlier columns were already pruned against this very set
            edges = self._lookup(col, alive)
            self.columns[k] = _Column(alive, edges.astype(np.int32))
            alive = np.unique(self._src[edges])

    def lattice_entries(self) -> int:
        return int(sum(len(c.edges) for c in self.columns))

    def compression_ratio(self) -> float:
        """Uncompressed lattice size (N per sample) over the entries actually stored."""
        stored = self.lattice_entries()
        return float(self.graph.n_nodes * len(self.columns) / stored) if stored else 1.0

    def best_node(self) -> int:
        """Lowest (broken constraints, cost) node at the current sample."""
        order = np.lexsort((self.G, self.Gr))
        return int(order[0])

    def backtrace(self, node: int, n_steps: int) -> tuple[np.ndarray, np.ndarray]:
        """Nodes and arriving edges of the path ending at `node` now, for the last `n_steps` + 1 samples
        (oldest first; the oldest sample's edge is -1 if it is the first sample, else its arriving edge)."""
        n_steps = min(n_steps, len(self.columns))
        nodes = np.empty(n_steps + 1, dtype=np.int64)
        edges = np.full(n_steps + 1, -1, dtype=np.int64)
        nodes[-1] = node
        for i in range(n_steps):
            col = self.columns[len(self.columns) - 1 - i]
            e = int(self._lookup(col, np.array([nodes[n_steps - i]]))[0])
            edges[n_steps - i] = e
            nodes[n_steps - i - 1] = self._src[e]
        if n_steps < len(self.columns):
            col = self.columns[len(self.columns) - 1 - n_steps]
            edges[0] = int(self._lookup(col, np.array([nodes[0]]))[0])
        return nodes, edges

    def global_states(self, node: int, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ground position and heading along a back-traced path, by undoing its edges from the current state
        of `node` (the values the search carried, without storing them per sample). Vectorised inverse of
        eq. 5: heading[i] = O_end - sum_{m>i} dh_m, ground[i] = P_end - sum_{m>i} R(heading[m-1]) d_m."""
        e = np.asarray(edges[1:], dtype=np.intp)
        dh = self._dh[e]
        after = np.r_[np.cumsum(dh[::-1])[::-1], 0.0]  # after[i] = sum of dh over edges later than sample i
        heading = self.O[node] - after
        steps = rotate_ground(np.stack([self._dpx[e], self._dpz[e]], axis=1), heading[:-1])
        back = np.concatenate([np.cumsum(steps[::-1], axis=0)[::-1], np.zeros((1, 2))])
        return self.P[node] - back, wrap_angle(heading)

    def drop_before(self, time: int) -> None:
        """Forget columns of samples earlier than `time` (already emitted by a fixed-lag decoder)."""
        n_drop = max(0, min(len(self.columns), time - self.first_column_time))
        if n_drop:
            del self.columns[:n_drop]
            self.first_column_time += n_drop


def constraint_penalties(constraints: list[Constraint], n_nodes: int, n_samples: int) -> dict[int, np.ndarray]:
    """Per-sample broken-constraint counts C_r(n, t) (only samples with an active constraint appear)."""
    out: dict[int, np.ndarray] = {}
    for c in constraints:
        if c.node_mask.shape != (n_nodes,):
            raise ValueError(f"constraint mask has shape {c.node_mask.shape}, graph has {n_nodes} nodes")
        for t in range(max(0, c.frame - c.tolerance_frames), min(n_samples, c.frame + c.tolerance_frames + 1)):
            out[t] = out.get(t, np.zeros(n_nodes)) + (~c.node_mask)
    return out


def _sample(obs: Observations, t: int) -> tuple[np.ndarray | None, np.ndarray | None, float | None]:
    acc = None if obs.acc_g is None else obs.acc_g[t]
    pos = None if obs.position_m is None else obs.position_m[t]
    head = None if obs.heading_rad is None else float(obs.heading_rad[t])
    return acc, pos, head


class ViterbiSearch:
    """Batch search: the best path for a whole input sequence."""

    def __init__(self, graph: MotionGraph, weights: SearchWeights = SearchWeights(), prune_every: int = 32) -> None:
        self.graph = graph
        self.weights = weights
        self.prune_every = prune_every

    def run(self, obs: Observations, constraints: list[Constraint] | None = None) -> SearchResult:
        lattice = ViterbiLattice(self.graph, self.weights, obs.sensor_indices, self.prune_every)
        penalties = constraint_penalties(constraints or [], self.graph.n_nodes, obs.n_samples)
        for t in range(obs.n_samples):
            lattice.step(*_sample(obs, t), penalties.get(t))
        return finish(lattice)


def finish(lattice: ViterbiLattice) -> SearchResult:
    """Back-trace the best path from the current state of the lattice (end of the sequence)."""
    lattice.prune()
    best = lattice.best_node()
    nodes, edges = lattice.backtrace(best, len(lattice.columns))
    ground, heading = lattice.global_states(best, edges)
    return SearchResult(nodes=nodes, edges=edges, ground_m=ground, heading_rad=heading,
                        cost=float(lattice.G[best]), broken_constraints=int(lattice.Gr[best]),
                        compression_ratio=lattice.compression_ratio(), lattice_entries=lattice.lattice_entries())
