"""Viterbi search over a motion graph (seed 000 sections 5-5.4), as whole-array numpy operations.

Per input sample every path is extended by one edge: G(n,t) = min over edges e=(m->n) of L(e,t) + G(m,t-1), with
L = W_A C_A + W_P C_P + W_O C_O (eqs. 4, 6, 7). The minimum over incoming edges is taken block-wise over edges
grouped by the destination's in-degree (`layout.EdgeLayout`; it replaced `np.minimum.reduceat`, whose
per-segment overhead dominated). C_A is computed once per metadata row (||E||^2 precomputed, the square
expanded) and gathered per edge. Each path carries its own global ground position and heading (eq. 5), so the
position and heading costs are per edge; they are evaluated in each source node's local frame
(||P + R(O) d - M|| = ||R(-O)(P - M) + d||), which moves the rotation from the E edges to the N nodes.

Human constraints (eq. 8) add a count of broken requirements G_r, compared before G: only incoming edges whose
source has the fewest broken constraints compete.

Back-pointers are int32 edge indices, one column per sample; survivor-path memory reduction (Abbasfar & Yao)
periodically back-traces from every live node and keeps, per column, only the entries some survivor uses.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

try:  # numba is in the `engine` extra: the headless gateway install does not carry a JIT compiler it never uses
    from . import kernels
except ImportError:  # pragma: no cover - exercised only on an install without the extra
    kernels = None
from .geometry import TWO_PI, wrap_angle
from .graph import MotionGraph
from .layout import EdgeLayout


KERNELS = ("numba", "numpy")
DEFAULT_KERNEL = "numba" if kernels is not None else "numpy"  # identical results; numba is 1.5-2.3x faster
ACC_BATCH = 16  # batch search computes C_A rows for this many samples per pass over the metadata


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
    so the two give identical paths when the lag covers the whole sequence.

    Internals, all for speed on large graphs: per-edge arrays are in `EdgeLayout` order (grouped by the
    destination's in-degree) so the minimum over incoming edges is a few whole-array comparisons; nodes are
    renumbered so the nodes with incoming edges come first in layout order (updates are slices, not
    scatters); ground positions are complex numbers x + iz and each path's heading is also kept as
    e^{-iO}, so moving an offset into the world is one complex multiply (R(h) v = v e^{-ih}) and the
    position cost is one complex gather + add + abs. Back-pointer columns hold graph edge ids."""

    def __init__(self, graph: MotionGraph, weights: SearchWeights = SearchWeights(),
                 sensor_indices: tuple[int, ...] | None = None, prune_every: int = 32,
                 kernel: str = DEFAULT_KERNEL) -> None:
        if kernel not in KERNELS:
            raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
        if kernel == "numba" and kernels is None:
            raise ValueError("kernel 'numba' needs numba: pip install 'courtside[engine]'")
        self.graph = graph
        self.weights = weights
        self.prune_every = prune_every
        self.kernel = kernel  # "numba": compiled fused step (kernels.py); "numpy": the reference, bit-identical
        # Without position/heading costs the search is Markov and needs no per-path global state: positions
        # along the chosen path are integrated afterwards (saves ~7 gathers of N per sample).
        self.track_global = weights.position != 0 or weights.heading != 0
        sel = list(range(graph.n_sensors)) if sensor_indices is None else list(sensor_indices)
        self.n_sensors = len(sel)
        e = graph.meta_acc_g[:, sel, :].reshape(len(graph.meta_acc_g), -1).astype(np.float32)
        self._meta_acc_sq = np.einsum("ij,ij->i", e.astype(np.float64), e.astype(np.float64)).astype(np.float32)
        self._dots = np.empty(len(e), dtype=np.float32)
        self._meta_acc_t = np.ascontiguousarray(e.T)  # (3S, M): one contiguous row per sensor axis
        self._axpy = np.empty(len(e), dtype=np.float32) if kernel == "numpy" else None
        self.layout = EdgeLayout(graph.edge_dst, graph.n_nodes)
        n = graph.n_nodes
        self.n_seg = len(self.layout.nodes)
        rest = np.setdiff1d(np.arange(n), self.layout.nodes)
        self._to_graph = np.r_[self.layout.nodes, rest].astype(np.intp)  # internal id -> graph node
        self._to_internal = np.empty(n, dtype=np.intp)
        self._to_internal[self._to_graph] = np.arange(n)
        order = self.layout.order
        self._edge_id = order.astype(np.int32)
        self._src = self._to_internal[graph.edge_src[order]]
        self._meta = graph.edge_meta[order].astype(np.intp)
        dpos = graph.meta_dpos_m[:, 0] + 1j * graph.meta_dpos_m[:, 1]
        self._d = dpos[self._meta]
        self._dh = graph.meta_dheading_rad[self._meta]
        self._d32 = self._d.astype(np.complex64)  # costs are evaluated in float32 (half the memory traffic)
        self._dh32 = self._dh.astype(np.float32)
        self._rot_dh = np.exp(-1j * self._dh)
        self._arrival = graph.node_arrival[self._to_graph]
        self._graph_src = graph.edge_src.astype(np.intp)
        self._graph_d = dpos[graph.edge_meta]
        self._graph_dh = graph.meta_dheading_rad[graph.edge_meta]
        n_e = len(order)
        if kernel == "numpy":
            self._cost = np.empty(n_e, dtype=np.float32)
            self._buf1 = np.empty(n_e, dtype=np.float32)
            self._buf2 = np.empty(n_e, dtype=np.float32)
            self._cbuf = np.empty(n_e, dtype=np.complex64)
        else:
            bl = self.layout.blocks
            self._blocks = tuple(np.array(v, dtype=np.int64) for v in (
                [b.offset for b in bl], [b.degree for b in bl], [b.count for b in bl], [b.nodes.start for b in bl]))
            self._src32 = self._src.astype(np.int32)
            self._meta32 = self._meta.astype(np.int32)
            self._cost = np.empty(n_e, dtype=np.float32)
            self._win = np.empty(self.n_seg, dtype=np.int64)
            self._u32 = np.empty(n, dtype=np.complex64)
            self._hd32 = np.empty(n, dtype=np.float32)
            self._grmin = np.empty(self.n_seg)
            self._zero_rows = np.zeros(len(e), dtype=np.float32)  # no acc term: adds exactly +0
            self._no_f64 = np.empty(0)
            self._no_state = (np.empty(0, dtype=complex), np.empty(0), np.empty(0, dtype=complex))
        self.cost_offset = 0.0  # G is float32 kept relative to its minimum (the offset is summed in float64)
        self.columns: list[_Column] = []
        self.t = -1  # index of the last sample consumed
        self.first_column_time = 1  # time of columns[0]
        self._since_prune = 0

    # ----- costs --------------------------------------------------------------------------------
    def _acc_rows(self, acc_g: np.ndarray | None) -> np.ndarray | None:
        """W_A * C_A for every metadata row (eq. 4) with the square expanded: ||E||^2 is precomputed, and
        the dot products E.M are 3S row-axpys over the transposed float32 metadata. (A BLAS GEMV on the
        tall-skinny (M, 3S) matrix measured 2-5x slower here -- OpenBLAS threads fight over shared cores --
        and elementwise axpys give bit-identical rows whether a sample comes alone (online) or in a batch.)"""
        if acc_g is None or self.n_sensors == 0 or self.weights.acc == 0:
            return None
        m = np.asarray(acc_g, dtype=np.float64).reshape(-1)
        if m.size != 3 * self.n_sensors:
            raise ValueError(f"expected {self.n_sensors} sensors x 3 axes, got shape {np.shape(acc_g)}")
        m32 = m.astype(np.float32)
        if self.kernel == "numba":
            return self.acc_rows_batch(m[None])[0]
        dots, tmp = self._dots, self._axpy
        np.multiply(self._meta_acc_t[0], m32[0], out=dots)
        for i in range(1, len(m32)):
            np.multiply(self._meta_acc_t[i], m32[i], out=tmp)
            dots += tmp
        dots *= np.float32(-2.0)
        dots += self._meta_acc_sq
        dots += np.float32(m @ m)
        dots *= np.float32(self.weights.acc / self.n_sensors)
        return dots

    def acc_rows_batch(self, acc_g: np.ndarray) -> np.ndarray:
        """`_acc_rows` of B samples (B, S', 3) at once -> (B, M) float32, bit-identical per row (compiled: the
        metadata is read once per batch instead of once per sample). Batch search feeds these to `step`."""
        m = np.asarray(acc_g, dtype=np.float64).reshape(len(acc_g), -1)
        if m.shape[1] != 3 * self.n_sensors:
            raise ValueError(f"expected {self.n_sensors} sensors x 3 axes, got shape {np.shape(acc_g)}")
        out = np.empty((len(m), self._meta_acc_t.shape[1]), dtype=np.float32)
        mm = np.array([np.float32(v @ v) for v in m], dtype=np.float32)
        scale = np.full(len(m), self.weights.acc / self.n_sensors, dtype=np.float32)
        kernels.acc_rows(self._meta_acc_t, self._meta_acc_sq, m.astype(np.float32), mm, scale, out)
        return out

    # ----- stepping -----------------------------------------------------------------------------
    def start(self, acc_g: np.ndarray | None, position_m: np.ndarray | None, heading_rad: float | None,
              penalty: np.ndarray | None = None) -> None:
        """First sample: every node may start a path; its cost is the arrival row's C_A, global state = input."""
        n = self.graph.n_nodes
        rows = self._acc_rows(acc_g)
        self._G = np.zeros(n, dtype=np.float32) if rows is None else rows[self._arrival]
        self._pos_known = not (position_m is None or np.any(np.isnan(position_m)))
        self._head_known = not (heading_rad is None or np.isnan(heading_rad))
        pos = np.asarray(position_m, float) if self._pos_known else np.zeros(2)
        head = float(heading_rad) if self._head_known else 0.0
        self.start_state = (complex(pos[0], pos[1]), head)
        if self.track_global:
            self._P = np.full(n, pos[0] + 1j * pos[1])
            self._O = np.full(n, head)  # not wrapped: it only ever enters costs through wrap-safe terms
            self._rot = np.full(n, np.exp(-1j * head))
            spare_state = (np.empty(n, dtype=complex), np.empty(n), np.empty(n, dtype=complex))
        else:
            self._P = self._O = self._rot = None
            spare_state = (None, None, None)
        self._spare = (np.empty(n, dtype=np.float32),) + spare_state
        self._Gr = np.zeros(n) if penalty is None else np.asarray(penalty, float)[self._to_graph]
        self.constrained = penalty is not None
        self.t = 0

    def _edge_costs(self, acc_g, position_m, heading_rad) -> np.ndarray:
        """L(e, t) + G(src, t-1) for every edge (layout order), in preallocated float32 buffers.

        _narrow: gathering float64/complex128 node values into the float32/complex64 buffers intermittently
        reports "invalid value encountered in cast" although every value is finite (checked: no NaN/inf in
        the sources when it fires); numpy's SIMD cast picks up a stale floating-point flag. The two narrowing
        gathers therefore run under errstate(invalid="ignore")."""
        src, cost, b1, b2 = self._src, self._cost, self._buf1, self._buf2
        np.take(self._G, src, out=cost, mode="clip")
        rows = self._acc_rows(acc_g)
        if rows is not None:
            np.take(rows, self._meta, out=b1, mode="clip")
            cost += b1
        if position_m is not None and not np.any(np.isnan(position_m)) and self.weights.position != 0:
            u = (self._P - (position_m[0] + 1j * position_m[1])) * np.conj(self._rot)  # R(-O)(P - M)
            cb = self._cbuf
            with np.errstate(invalid="ignore"):  # see _narrow: the float64 -> float32 cast raises a stale flag
                np.take(u, src, out=cb, mode="clip")
            cb += self._d32
            np.abs(cb, out=b1)
            if self.weights.position != 1:
                b1 *= self.weights.position
            cost += b1
        if heading_rad is not None and not np.isnan(heading_rad) and self.weights.heading != 0:
            hd = self._O - heading_rad
            hd -= TWO_PI * np.round(hd / TWO_PI)
            with np.errstate(invalid="ignore"):  # see _narrow
                np.take(hd, src, out=b1, mode="clip")
            b1 += self._dh32  # in [-2pi, 2pi]: |wrap(x)| = min(|x|, 2pi - |x|)
            np.abs(b1, out=b1)
            np.subtract(np.float32(TWO_PI), b1, out=b2)
            np.minimum(b1, b2, out=b1)
            if self.weights.heading != 1:
                b1 *= self.weights.heading
            cost += b1
        return cost

    def _late_start(self, position_m, heading_rad) -> tuple[bool, bool]:
        """Is this sample the first camera fix of a take that started without one? (position, heading)"""
        first_pos = (not self._pos_known and position_m is not None and not np.any(np.isnan(position_m)))
        first_head = (not self._head_known and heading_rad is not None and not np.isnan(heading_rad))
        return first_pos, first_head

    def step(self, acc_g: np.ndarray | None, position_m: np.ndarray | None, heading_rad: float | None,
             penalty: np.ndarray | None = None, rows: np.ndarray | None = None) -> None:
        """Advance every path by one edge for the next sample (O(E) array work). `rows`: this sample's
        `acc_rows_batch` row, if the caller computed it in a batch (compiled kernel only)."""
        if rows is not None and self.kernel != "numba":
            raise ValueError("precomputed acc rows need the numba kernel")
        if self.t < 0:
            self.start(acc_g, position_m, heading_rad, penalty)
            return
        first_pos, first_head = self._late_start(position_m, heading_rad) if self.track_global else (False, False)
        pos = None if position_m is None or first_pos else np.asarray(position_m, float)
        head = None if first_head else heading_rad
        self.constrained |= penalty is not None
        k = self.n_seg
        # write the new state into the spare buffers (double buffering: no per-step allocation of N arrays)
        G, P, O, rot = self._spare
        Gr = np.full(self.graph.n_nodes, np.inf) if self.constrained else None
        if self.kernel == "numba":
            col = self._step_compiled(acc_g, pos, head, G, P, O, rot, Gr, rows)
        else:
            col = self._step_numpy(acc_g, pos, head, G, P, O, rot, Gr)
        G[k:] = np.inf
        low = G[:k].min()
        if np.isfinite(low):
            G[:k] -= low
            self.cost_offset += float(low)
        if self.track_global:
            P[k:], O[k:], rot[k:] = self._P[k:], self._O[k:], self._rot[k:]
        if self.constrained:
            if penalty is not None:
                Gr += np.asarray(penalty, float)[self._to_graph]
            Gr[~np.isfinite(G)] = np.inf
            self._Gr = Gr
        self._spare = (self._G, self._P, self._O, self._rot)
        self._G, self._P, self._O, self._rot = G, P, O, rot  # (P, O, rot untouched if not tracked)
        if first_pos:  # a take that started without a camera fix: the first fix initialises every path (eq. 5)
            self._P[:] = complex(position_m[0], position_m[1])
            self._pos_known = True
        if first_head:
            self._O[:] = heading_rad
            self._rot[:] = np.exp(-1j * heading_rad)
            self._head_known = True
        self.columns.append(_Column(None, col))
        self.t += 1
        self._since_prune += 1
        if self.prune_every and self._since_prune >= self.prune_every:
            self.prune()

    def _step_numpy(self, acc_g, pos, head, G, P, O, rot, Gr) -> np.ndarray:
        """Reference step in whole-array numpy: writes the new G[:k] (not normalised), P/O/rot[:k] (if tracked)
        and Gr[:k] (if constrained); returns the back-pointer column (graph edge ids, int32)."""
        cost = self._edge_costs(acc_g, pos, head)
        if self.constrained:  # eq. 8: only edges from sources with the fewest broken constraints compete
            gr_e = self._Gr[self._src]
            cost[gr_e > self.layout.broadcast(self.layout.block_min(gr_e))] = np.inf
        seg_min, win = self.layout.argmin(cost)
        wsrc = self._src[win]
        k = self.n_seg
        G[:k] = seg_min
        if self.track_global:
            np.take(self._rot, wsrc, out=rot[:k], mode="clip")
            np.take(self._P, wsrc, out=P[:k], mode="clip")
            P[:k] += self._d[win] * rot[:k]  # eq. 5: P(n,t) = P(m,t-1) + R(O(m,t-1)) d(v)
            np.take(self._O, wsrc, out=O[:k], mode="clip")
            O[:k] += self._dh[win]
            rot[:k] *= self._rot_dh[win]
        if self.constrained:
            Gr[:k] = self._Gr[wsrc]
        return self._edge_id[win]

    def _step_compiled(self, acc_g, pos, head, G, P, O, rot, Gr, rows=None) -> np.ndarray:
        """The same step as `_step_numpy` in compiled passes (kernels.py): node terms, edge costs, constraint
        mask, per-node argmin + winners' state update. Bit-identical to the reference."""
        w = self.weights
        if rows is None:
            rows = self._acc_rows(acc_g)
        if rows is None:
            rows = self._zero_rows
        use_pos = pos is not None and not np.any(np.isnan(pos)) and w.position != 0
        use_head = head is not None and not np.isnan(head) and w.heading != 0
        cost, track = self._cost, self.track_global
        if use_pos or use_head:
            kernels.node_terms(self._P, self._rot, complex(pos[0], pos[1]) if use_pos else 0j, self._O,
                               float(head) if use_head else 0.0, use_pos, use_head, self._u32, self._hd32)
            kernels.edge_costs_global(self._src32, self._meta32, self._d32, self._dh32, self._G, rows, self._u32,
                                      self._hd32, np.float32(w.position if use_pos else 0.0),
                                      np.float32(w.heading if use_head else 0.0), cost)
        else:
            kernels.edge_costs_acc(self._src32, self._meta32, self._G, rows, cost)
        if self.constrained:
            kernels.mask_constraints(*self._blocks, self._src32, self._Gr, self._grmin, cost)
        col = np.empty(self.n_seg, dtype=np.int32)
        no = self._no_state
        kernels.argmin_update(*self._blocks, cost, self._src32, self._edge_id, self._d, self._dh, self._rot_dh,
                              self._P if track else no[0], self._O if track else no[1],
                              self._rot if track else no[2], track, self._Gr, self.constrained, G,
                              P if track else no[0], O if track else no[1], rot if track else no[2],
                              self._no_f64 if Gr is None else Gr, self._win, col)
        return col

    # ----- state by graph node ------------------------------------------------------------------
    def cost_of(self, node: int) -> float:
        return float(self._G[self._to_internal[node]]) + self.cost_offset

    def broken_of(self, node: int) -> int:
        return int(self._Gr[self._to_internal[node]])

    def best_node(self) -> int:
        """Graph node with the lowest (broken constraints, cost) at the current sample."""
        if not self.constrained:
            return int(self._to_graph[np.argmin(self._G)])
        fewest = self._Gr == self._Gr.min()
        return int(self._to_graph[np.argmin(np.where(fewest, self._G, np.inf))])

    # ----- path memory --------------------------------------------------------------------------
    def _lookup(self, col: _Column, nodes: np.ndarray) -> np.ndarray:
        """Arriving graph edge of each graph node in `nodes` from one column."""
        idx = self._to_internal[nodes] if col.nodes is None else np.searchsorted(col.nodes, nodes)
        return col.edges[idx].astype(np.intp)

    def prune(self) -> None:
        """Survivor-path memory reduction: keep only lattice entries on some live node's back-trace.
        Node sets are kept sorted via a mark array (O(N) per column; np.unique's hashing was 20x slower)."""
        self._since_prune = 0
        alive = self._sorted_set(self._to_graph[np.isfinite(self._G)])
        for k in range(len(self.columns) - 1, -1, -1):
            col = self.columns[k]
            if col.nodes is not None and len(col.nodes) == len(alive) and np.array_equal(col.nodes, alive):
                break  # earlier columns were already pruned against this very set
            edges = self._lookup(col, alive)
            self.columns[k] = _Column(alive, edges.astype(np.int32))
            alive = self._sorted_set(self._graph_src[edges])

    def _sorted_set(self, nodes: np.ndarray) -> np.ndarray:
        """Distinct graph node ids of `nodes`, ascending."""
        mark = np.zeros(self.graph.n_nodes, dtype=bool)
        mark[nodes] = True
        return np.flatnonzero(mark)

    def lattice_entries(self) -> int:
        return int(sum(len(c.edges) for c in self.columns))

    def compression_ratio(self) -> float:
        """Uncompressed lattice size (N per sample) over the entries actually stored."""
        stored = self.lattice_entries()
        return float(self.graph.n_nodes * len(self.columns) / stored) if stored else 1.0

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
            nodes[n_steps - i - 1] = self._graph_src[e]
        if n_steps < len(self.columns):
            col = self.columns[len(self.columns) - 1 - n_steps]
            edges[0] = int(self._lookup(col, np.array([nodes[0]]))[0])
        return nodes, edges

    def global_states(self, node: int, edges: np.ndarray,
                      start: tuple[complex, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Ground position (T, 2) and heading (T,) along a back-traced path ending at `node` now.

        With global costs these are the values the search carried, recovered by undoing the path's edges from
        `node`'s current state (never stored per sample); vectorised inverse of eq. 5:
        O[i] = O_end - sum_{m>i} dh_m, P[i] = P_end - sum_{m>i} R(O[m-1]) d_m.
        Without them (Markov search) eq. 5 is integrated forward from `start` = (ground x + iz, heading) of
        the path's first sample (default: the first input sample)."""
        e = np.asarray(edges[1:], dtype=np.intp)
        dh = self._graph_dh[e]
        if self.track_global:
            i = self._to_internal[node]
            heading = self._O[i] - np.r_[np.cumsum(dh[::-1])[::-1], 0.0]  # minus the dh of later edges
            steps = self._graph_d[e] * np.exp(-1j * heading[:-1])
            ground = self._P[i] - np.r_[np.cumsum(steps[::-1])[::-1], 0.0]
        else:
            p0, o0 = self.start_state if start is None else start
            heading = o0 + np.r_[0.0, np.cumsum(dh)]
            ground = p0 + np.r_[0.0, np.cumsum(self._graph_d[e] * np.exp(-1j * heading[:-1]))]
        return np.stack([ground.real, ground.imag], axis=1), wrap_angle(heading)

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

    def __init__(self, graph: MotionGraph, weights: SearchWeights = SearchWeights(), prune_every: int = 32,
                 kernel: str = DEFAULT_KERNEL) -> None:
        self.graph = graph
        self.weights = weights
        self.prune_every = prune_every
        self.kernel = kernel

    def run(self, obs: Observations, constraints: list[Constraint] | None = None) -> SearchResult:
        lattice = ViterbiLattice(self.graph, self.weights, obs.sensor_indices, self.prune_every, self.kernel)
        penalties = constraint_penalties(constraints or [], self.graph.n_nodes, obs.n_samples)
        batch = lattice.kernel == "numba" and obs.acc_g is not None and lattice.n_sensors and self.weights.acc != 0
        rows = None
        for t in range(obs.n_samples):
            if batch and t % ACC_BATCH == 0:  # C_A rows of the next samples in one pass over the metadata
                rows = lattice.acc_rows_batch(obs.acc_g[t:t + ACC_BATCH])
            lattice.step(*_sample(obs, t), penalties.get(t), rows[t % ACC_BATCH] if batch and t else None)
        return finish(lattice)


def finish(lattice: ViterbiLattice) -> SearchResult:
    """Back-trace the best path from the current state of the lattice (end of the sequence)."""
    lattice.prune()
    best = lattice.best_node()
    nodes, edges = lattice.backtrace(best, len(lattice.columns))
    ground, heading = lattice.global_states(best, edges)
    return SearchResult(nodes=nodes, edges=edges, ground_m=ground, heading_rad=heading,
                        cost=lattice.cost_of(best), broken_constraints=lattice.broken_of(best),
                        compression_ratio=lattice.compression_ratio(), lattice_entries=lattice.lattice_entries())
