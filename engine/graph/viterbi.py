"""Viterbi search over a motion graph (seed 000 sections 5-5.4), one O(E) pass of array work per sample.

Per input sample every path is extended by one edge: G(n,t) = min over edges e=(m->n) of L(e,t) + G(m,t-1), with
L = W_A C_A + W_P C_P + W_O C_O (eqs. 4, 6, 7). C_A is computed once per metadata row (||E||^2 precomputed, the
square expanded) and gathered per edge. Each path carries its own global ground position and heading (eq. 5), so
the position and heading costs are per edge; they are evaluated in each source node's frame
(||P + R(O) d - M|| = ||R(-O)(P - M) + d||), which moves the rotation from the E edges to the N nodes.

The edges are visited in `edge_runs.EdgeRuns` order: long diagonal runs (clip frame -> next frame and the like,
whose sources and destinations are contiguous node ranges) and then the scattered rest, a node's incoming edges in
increasing search index with ties to the earliest. Costs and per-path state are float32 (G kept relative to its
minimum, the offset summed in float64; headings wrapped to [-pi, pi] at every step, their cos/sin recomputed from
them by `trig32` rather than stored), which halves the memory traffic that bounds the step.

Human constraints (eq. 8) add a count of broken requirements G_r, compared before G: only incoming edges whose
source has the fewest broken constraints compete.

Back-pointers are int32 search indices, one column per sample; survivor-path memory reduction (Abbasfar & Yao)
periodically back-traces from every live node and keeps, per column, only the entries some survivor uses.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine import progress
from engine.errors import CourtsideError
from engine.mocap.orientation_calibration import OrientationCalibration

from . import kernels_numpy
from .edge_runs import EdgeRuns
from .geometry import wrap_angle
from .graph import MotionGraph
from .gravity_term import GravityTerm
from .orientation_term import OrientationTerm, places_sensors
from .sensor_weights import sensor_weights
from .warp import RootWarp, follow_camera

try:  # numba is in the `engine` extra: the headless gateway install does not carry a JIT compiler it never uses
    from . import kernels_numba
except ImportError:  # pragma: no cover - exercised only on an install without the extra
    kernels_numba = None

# the step's kernels by name: two modules with the same functions (compiled / numpy reference), identical results
BACKENDS = {"numba": kernels_numba, "numpy": kernels_numpy}
KERNELS = tuple(BACKENDS)
DEFAULT_KERNEL = "numba" if kernels_numba is not None else "numpy"  # numba is several times faster
PRUNE_EVERY = 64  # samples between survivor prunes: the newest columns cost most to prune (their survivor sets
# are large); measured 0.73 vs 0.38 ms per sample for 32 vs 64 on the 483k-edge graph; memory 64 x 4 B per node
PRUNE_HORIZON = 512  # samples (17 s at 30 Hz): columns pruned at this age or older are not pruned again
ACC_BATCH = 16  # batch search computes C_A rows for this many samples per pass over the metadata

class PathsExhaustedError(CourtsideError):
    """No path of the search is alive: the graph has dead ends and the take outlasted every path into them."""


@dataclass(frozen=True)
class SearchWeights:
    """Weights of eq. 6 (cost units: g^2, metres, radians; paper's best tennis setting: 0.5 / 1 / 1) and the
    search's memory.

    `forgetting` (per sample, 1 = seed 000's Viterbi) multiplies every path's accumulated cost before the next
    sample is added, so a path's cost is an exponentially weighted match over the last ~1 / (1 - forgetting)
    samples instead of over the whole take. Why: a held-out take is never in the database; the globally best
    path must explain minutes of motion with a few database clips, and on chained Bandai takes its poses were
    worse than a 0.5 s nearest neighbour on the same sensors (docs/engine-evaluation.md). With forgetting < 1 the
    search decides each sample `decision_frames` samples later from the best path at that moment (batch search
    and fixed-lag decoder alike, online.decide_with_forgetting): a back-trace from the end of the take would
    follow whatever clip the last samples matched."""

    acc: float = 0.5
    position: float = 1.0
    heading: float = 1.0
    forgetting: float = 1.0
    decision_frames: int = 0
    blend_paths: int = 1  # output pose = mean root-frame pose of the best this many paths at the decided sample
    orientation: float = 0.0  # weight of the orientation term relative to C_A (orientation_term.py); 0 = off,
    # and the term is skipped for samples without orientations (an acc-only take searches exactly as before)
    orientation_heading: float = 0.0  # share of its heading-relative-to-the-pelvis part (learnt yaw offsets)
    # against its tilt part; 0 = tilt alone (measured best: docs/engine-evaluation.md, "Orientations")
    calibrated_heading: float = 0.5  # the same share when an N-pose calibration gives the yaw offsets (nothing
    # to learn: measured better than tilt alone, docs/engine-evaluation.md)
    forearm_roll: float = 0.0  # with an orientation calibration: the weight of a worn forearm's roll about
    # its bone in the orientation term, against where the bone points (orientation_term.roll_axis_weights)
    gravity: float = 0.0  # weight of the tilt estimated from low-passed accelerations (gravity_term.py) when the
    # orientation term is off; 0 = off (docs/engine-evaluation.md, "Accelerations that listen")
    segment_pose: float = 1.0  # with orientations: how far each worn segment is turned from the played pose onto
    # its measured orientation (orientation_pose.py; 1 = all the way, 0 = play database poses as they are)
    hinge_share: float = 0.5  # share of a worn forearm's / shin's turn that the unworn upper arm / thigh takes about
    # the shoulder / hip (the played elbow / knee angle kept for that share; orientation_pose.py); 0 = only the
    # worn segment turns
    limb_prior_k: int = 64  # when posing: an unworn upper arm / thigh points where the k database poses nearest
    # in the worn forearm's / shin's orientation relative to the chest / pelvis (tilts alone without a
    # calibration) have it (limb_prior.py); 0 = the hinge share alone
    strap_refine_s: float = 20.0  # with orientations and an N-pose calibration: time constant (s) of the running
    # estimate of each sensor's strapping error (the athlete's posing error in the capture) from its measured-
    # against-played rotation (orientation_pose.SegmentPosing); 0 = trust the capture as it is
    tilt_from_acc_s: float = 0.2  # without orientations: the time constant (s) of the low-pass that gives each
    # worn segment's tilt from its accelerations for the posing (acc_tilt.py); 0 = play database poses as they are
    sensor_weighting: float = 0.0  # power of the per-sensor C_A weights from how much each sensor tells about
    # pose (sensor_weights.py); 0 = every sensor alike (off; a graph without joint rotations: always); negative
    # favours the less pose-specific sensors (camera_following: -4)

    def __post_init__(self) -> None:
        if self.blend_paths < 1 or (self.blend_paths > 1 and not self.forgets):
            raise ValueError(f"blend_paths must be >= 1, and 1 unless forgetting < 1 (the blend is of the best "
                             f"paths at each decided sample), got {self.blend_paths}")
        if not 0.0 < self.forgetting <= 1.0:
            raise ValueError(f"forgetting must be in (0, 1], got {self.forgetting}")
        if self.decision_frames < 0:
            raise ValueError(f"decision_frames must be >= 0, got {self.decision_frames}")

    @property
    def forgets(self) -> bool:
        return self.forgetting < 1.0

    @classmethod
    def camera_following(cls) -> "SearchWeights":
        """The search for a root that follows the camera (warp.RootWarp): weights 1 / 1 / 0.3, forgetting 0.9,
        decided 6 samples (0.2 s) later, the mean pose of the 8 best paths. With the root warped onto the camera
        the pose is the accelerometers' to choose: position / heading weights of 10 / 3 made the search pick
        whatever motion best explained the camera's small displacements (an in-place strike scored worse than
        the mean pose); 1 / 0.3 keep a loose speed / turning constraint. Forgetting 0.9 makes a path's cost a
        match over the last ~10 samples (0.85 was best under the small real-sensor gap, 0.93 under seed 000's
        large one); the blend of 8 paths averages nearly equally good matches (k-NN, as Tautges et al.'s OLNG).
        Measured on chained held-out Bandai takes: docs/engine-evaluation.md. Orientation term weight 1
        (orientation_term.py: at 1 its database spread equals the accelerations'); a take without orientations
        searches exactly as with 0. Sensor weighting power -4 (sensor_weights.py: the sensors whose accelerations
        tell less about the pose weigh more, so an arm doing what the database lacks pulls the search less; the
        posing turns that arm afterwards): gestures left out, accelerations only, 9.4 -> 8.7 cm, chained takes
        7.8 -> 7.6, turning walks 5.6 either way (chosen on those held-out contents)."""
        return cls(1.0, 1.0, 0.3, forgetting=0.9, decision_frames=6, blend_paths=8, orientation=1.0,
                   sensor_weighting=-4.0)


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
    quat_wxyz: np.ndarray | None = None  # (T, S', 4) sensor -> device earth (Z up, yaw per sensor), NaN = missing
    gyro_rps: np.ndarray | None = None  # (T, S', 3) rad/s in the sensor frame, NaN = missing
    orientation_calibration: OrientationCalibration | None = None  # of the S' sensors: how to read `quat_wxyz`
    # (yaw offsets + strapping from the N-pose capture; None = unknown yaws)

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
    blend_nodes: np.ndarray | None = None  # (T, k) nodes whose mean pose is the output (SearchWeights.blend_paths)


@dataclass
class _Column:
    """Back-pointers of one sample: `edges[i]` (a search index, see `EdgeRuns`) reached `nodes[i]`; nodes None
    = one entry per graph node (a full column not yet pruned)."""

    nodes: np.ndarray | None
    edges: np.ndarray  # int32
    pruned_age: int = -1  # the column's age (samples) when it was last pruned


def default_weights(warp: RootWarp) -> SearchWeights:
    """The search weights that go with ``warp``: the camera-following preset when the root follows the camera, the
    paper's otherwise — one rule for `courtside synthesize` and the console, so a take gives the same poses live
    and offline."""
    return SearchWeights.camera_following() if warp.active else SearchWeights()


class ViterbiLattice:
    """The running search state; `ViterbiSearch` (batch) and `FixedLagSynthesizer` (online) both drive it,
    so the two give identical paths when the lag covers the whole sequence.

    Per-node arrays are indexed by graph node id; per-edge arrays by search index (`EdgeRuns` order). Each path's
    global state is three float32 arrays: ground position (Px, Pz) m and heading O rad in [-pi, pi]."""

    def __init__(self, graph: MotionGraph, weights: SearchWeights = SearchWeights(),
                 sensor_indices: tuple[int, ...] | None = None, prune_every: int = PRUNE_EVERY,
                 kernel: str = DEFAULT_KERNEL, warp: RootWarp = RootWarp.off(),
                 orientation_calibration: OrientationCalibration | None = None) -> None:
        if kernel not in KERNELS:
            raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
        if BACKENDS[kernel] is None:
            raise ValueError(f"kernel {kernel!r} needs numba: pip install 'courtside[engine]'")
        self.graph = graph
        self.weights = weights
        self.prune_every = prune_every
        self.kernel = kernel
        self.kernels = BACKENDS[kernel]  # compiled passes (kernels_numba) or the numpy reference: bit-identical
        # Without position/heading costs the search is Markov and needs no per-path global state: positions
        # along the chosen path are integrated afterwards.
        self.track_global = weights.position != 0 or weights.heading != 0
        self.warp = warp  # root warping towards the camera (warp.py); off = seed 000's search exactly
        self._fixes: list[tuple[complex | None, float | None, bool]] = []  # per sample, for the output replay
        self.first_fix_time = 0  # time of _fixes[0]
        sel = list(range(graph.n_sensors)) if sensor_indices is None else list(sensor_indices)
        self.n_sensors = len(sel)
        m = len(graph.meta_acc_g)
        # (3S, M) float32: one contiguous row per sensor axis (a single copy: this runs once per search)
        acc_t = np.asarray(graph.meta_acc_g, dtype=np.float32)[:, sel, :].transpose(1, 2, 0).reshape(-1, m)
        # per-sensor weights: both sides of C_A's acc rows times sqrt(w) (None: every sensor alike, untouched)
        self._acc_scale = None
        if weights.sensor_weighting != 0 and self.n_sensors and graph.node_rotations is not None:
            self._acc_scale = np.repeat(np.sqrt(sensor_weights(graph, sel, weights.sensor_weighting)), 3)
            acc_t = (acc_t * self._acc_scale[:, None].astype(np.float32)).astype(np.float32)
        # the orientation term's features are extra rows of the same squared distance (orientation_term.py);
        # a sample without orientations uses the first 3S rows alone (a contiguous view)
        self.orientation = OrientationTerm(graph, sel, weights.orientation, weights.orientation_heading,
                                           calibration=orientation_calibration,
                                           calibrated_heading_share=weights.calibrated_heading,
                                           roll_share=weights.forearm_roll) \
            if weights.orientation > 0 and self.n_sensors and places_sensors(graph) else None
        self._encoder = None if self.orientation is None else self.orientation.encoder()
        self._gravity = None
        if self.orientation is None and weights.gravity > 0 and self.n_sensors:
            self.orientation = self._gravity = GravityTerm(graph, sel, weights.gravity)
        self._meta_acc_t = np.ascontiguousarray(
            acc_t if self.orientation is None else np.concatenate([acc_t, self.orientation.meta_rows_t]))
        widths = {3 * self.n_sensors, 6 * self.n_sensors, len(self._meta_acc_t)} if self.orientation else \
            {3 * self.n_sensors}  # acc; acc + tilt; acc + tilt + heading (orientation_term.py)
        self._meta_sq = {k: np.einsum("ij,ij->j", self._meta_acc_t[:k], self._meta_acc_t[:k],
                                      dtype=np.float64).astype(np.float32) for k in widths}  # by input width
        self.runs = EdgeRuns(graph.edge_src, graph.edge_dst, graph.edge_meta, graph.n_nodes)
        r = self.runs
        self._src, self._dst = r.src.astype(np.intp), r.dst.astype(np.intp)
        self._src32 = r.src.astype(np.int32)
        self._meta = r.meta.astype(np.intp)
        self._meta32 = r.meta.astype(np.int32)
        self._search_index32 = np.arange(len(r.src), dtype=np.int32)
        self._zero_rows = np.zeros(len(graph.meta_acc_g), dtype=np.float32)  # no acc term: adds exactly +0
        self._dx, self._dz = (graph.meta_dpos_m[self._meta, i].astype(np.float32) for i in (0, 1))
        self._dh = graph.meta_dheading_rad[self._meta].astype(np.float32)
        self._ra = np.empty(len(self._src), dtype=np.float32)  # per-edge W_A C_A (numpy / constrained steps)
        self._cost = np.empty(len(self._src), dtype=np.float32)  # per-edge cost (the numpy reference's fold)
        self._graph_src = graph.edge_src.astype(np.intp)
        dpos = graph.meta_dpos_m[:, 0] + 1j * graph.meta_dpos_m[:, 1]
        self._graph_d = dpos[graph.edge_meta]
        self._graph_dh = graph.meta_dheading_rad[graph.edge_meta]
        self._none32 = np.empty(0, dtype=np.float32)
        self._sc_cost = np.empty(len(self._src) - self.runs.n_run_edges, dtype=np.float32)
        self.cost_offset = 0.0  # G is float32 kept relative to its minimum (the offset is summed in float64);
        # with forgetting it is the sum of the per-sample minima (the best local match's cost per sample, undiscounted)
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
        self._check_width(m.size, np.shape(acc_g))
        return self.acc_rows_batch(m[None])[0]

    def acc_rows_batch(self, acc_g: np.ndarray) -> np.ndarray:
        """`_acc_rows` of B samples (B, S', 3) at once -> (B, M) float32, bit-identical per row (compiled: the
        metadata is read once per batch instead of once per sample). Whole-take searches feed these to `step`."""
        m = np.asarray(acc_g, dtype=np.float64).reshape(len(acc_g), -1)
        self._check_width(m.shape[1], np.shape(acc_g))
        if self._acc_scale is not None:
            m = m.copy()
            m[:, :len(self._acc_scale)] *= self._acc_scale
        out = np.empty((len(m), self._meta_acc_t.shape[1]), dtype=np.float32)
        width = m.shape[1]
        mm = np.array([np.float32(v @ v) for v in m], dtype=np.float32)
        scale = np.full(len(m), self.weights.acc / self.n_sensors, dtype=np.float32)
        self.kernels.acc_rows(self._meta_acc_t[:width], self._meta_sq[width], m.astype(np.float32), mm, scale, out)
        return out

    def _check_width(self, width: int, shape: tuple) -> None:
        if width not in self._meta_sq:
            raise ValueError(f"expected {self.n_sensors} sensors x 3 axes, got shape {shape}")

    def encode(self, acc_g: np.ndarray | None, quat_wxyz: np.ndarray | None) -> np.ndarray | None:
        """The C_A input of one sample: the accelerations, followed by the orientation features when the term is
        on and the sample has orientations (the encoder counts samples: once per sample, in order)."""
        if self._gravity is not None:
            feats = self._gravity.push(acc_g)
        else:
            feats = None if self._encoder is None else self._encoder.push(quat_wxyz)
        if acc_g is None or feats is None:
            return acc_g
        return np.concatenate([np.asarray(acc_g, float).reshape(-1, 3), feats])

    def learn_orientation(self, first: int, nodes: np.ndarray) -> None:
        """Samples first.. were decided as `nodes`: the orientation term's yaw-offset estimate learns from them
        (orientation_term.OrientationEncoder.learn; no-op without the term)."""
        if self._encoder is not None:
            self._encoder.learn(first, nodes)

    def _edge_rows(self, rows: np.ndarray) -> np.ndarray:
        """Each edge's W_A C_A (search order) from the per-metadata-row costs."""
        return np.take(rows, self._meta, out=self._ra)

    def _mask_constraints(self, ra: np.ndarray) -> None:
        """Eq. 8: an edge whose source has more broken constraints than another source of the same node never
        competes (its cost becomes +inf). Shared by both kernels; constraints are rare and short."""
        gr_src = self._Gr[self._src]
        fewest = np.full(self.graph.n_nodes, np.inf)
        for idx, d in self.runs.layers:
            fewest[d] = np.minimum(fewest[d], gr_src[idx])
        ra[gr_src > fewest[self._dst]] = np.inf

    # ----- stepping -----------------------------------------------------------------------------
    def _global_state(self, position_m: complex, heading_rad: float) -> tuple[np.ndarray, ...]:
        """Every node's (Px, Pz, O) set to one ground position and heading (eq. 5's initial state)."""
        values = (position_m.real, position_m.imag, float(wrap_angle(heading_rad)))
        return tuple(np.full(self.graph.n_nodes, v, dtype=np.float32) for v in values)

    def start(self, acc_g: np.ndarray | None, position_m: np.ndarray | None, heading_rad: float | None,
              penalty: np.ndarray | None = None, quat_wxyz: np.ndarray | None = None) -> None:
        """First sample: every node may start a path; its cost is the arrival row's C_A, global state = input."""
        n = self.graph.n_nodes
        rows = self._acc_rows(self.encode(acc_g, quat_wxyz))
        self._G = np.zeros(n, dtype=np.float32) if rows is None else rows[self.graph.node_arrival]
        self._spare_G = np.empty(n, dtype=np.float32)
        self._win = np.empty(n, dtype=np.int32)
        self._pos_known = not (position_m is None or np.any(np.isnan(position_m)))
        self._head_known = not (heading_rad is None or np.isnan(heading_rad))
        pos = np.asarray(position_m, float) if self._pos_known else np.zeros(2)
        head = float(heading_rad) if self._head_known else 0.0
        self.start_state = (complex(pos[0], pos[1]), head)
        if self.track_global:
            self._state = self._global_state(*self.start_state)
            self._spare_state = tuple(a.copy() for a in self._state)
            self._terms = tuple(np.empty(n, dtype=np.float32) for _ in range(5))  # C, Sn, ux, uz, th
        self._Gr = np.zeros(n) if penalty is None else np.asarray(penalty, float)
        self.constrained = penalty is not None
        self.t = 0
        if self.warp.active:
            self._record_fix(position_m, heading_rad, False)

    def _late_start(self, position_m, heading_rad) -> tuple[bool, bool]:
        """Is this sample the first camera fix of a take that started without one? (position, heading)"""
        first_pos = (not self._pos_known and position_m is not None and not np.any(np.isnan(position_m)))
        first_head = (not self._head_known and heading_rad is not None and not np.isnan(heading_rad))
        return first_pos, first_head

    def step(self, acc_g: np.ndarray | None, position_m: np.ndarray | None, heading_rad: float | None,
             penalty: np.ndarray | None = None, rows: np.ndarray | None = None,
             quat_wxyz: np.ndarray | None = None) -> None:
        """Advance every path by one edge for the next sample (O(E) array work). `rows`: this sample's
        `acc_rows_batch` row, if the caller computed it in a batch; `quat_wxyz` (S', 4): the sensors' device-earth
        orientations (used with `SearchWeights.orientation` > 0)."""
        if self.t < 0:
            self.start(acc_g, position_m, heading_rad, penalty, quat_wxyz)
            return
        acc_g = self.encode(acc_g, quat_wxyz)
        first_pos, first_head = self._late_start(position_m, heading_rad) \
            if self.track_global or self.warp.active else (False, False)
        w = self.weights
        fix_pos = (self.track_global and not first_pos and position_m is not None
                   and not np.any(np.isnan(position_m)))
        fix_head = self.track_global and not first_head and heading_rad is not None and not np.isnan(heading_rad)
        use_pos = fix_pos and w.position != 0
        use_head = fix_head and w.heading != 0
        self.constrained |= penalty is not None
        rows = self._acc_rows(acc_g) if rows is None else rows
        rows = self._zero_rows if rows is None else rows
        # the compiled passes read rows by metadata row, the reference by edge; a constrained step masks by edge
        ra = self._edge_rows(rows) if self.constrained else None
        if self.constrained:
            self._mask_constraints(ra)
        if self.track_global:  # cos/sin of every path's heading, and the cost terms if this sample has a fix
            mpos = np.asarray(position_m, float) if use_pos else np.zeros(2)
            self._node_terms(mpos, float(wrap_angle(heading_rad)) if use_head else 0.0)
        terms = self._terms[2:] if use_pos or use_head else None
        wp = np.float32(w.position if use_pos else 0.0)
        wh = np.float32(w.heading if use_head else 0.0)
        best, win = self._spare_G, self._win
        best.fill(np.inf)
        win.fill(-1)
        if w.forgets:  # the accumulated costs fade (SearchWeights.forgetting); float32, the same for both kernels
            self._G *= np.float32(w.forgetting)
        self.kernels.fold(self, rows, ra, terms, wp, wh, best, win)
        if self.track_global:
            self._state, self._spare_state = self._spare_state, self._state
            if self.warp.active and (fix_pos or fix_head):
                self._warp(position_m if fix_pos else None, heading_rad if fix_head else None)
        low = best.min()
        if np.isfinite(low):
            best -= low
            self.cost_offset += float(low)
        if self.constrained:
            Gr = np.where(win >= 0, self._Gr[self._src[win]], np.inf)
            if penalty is not None:
                Gr += np.asarray(penalty, float)
            Gr[~np.isfinite(best)] = np.inf
            self._Gr = Gr
        self._spare_G, self._G = self._G, best
        if self.warp.active:
            self._record_fix(position_m, heading_rad, first_pos or first_head)
        if first_pos or first_head:  # a take that started without a camera fix: the first fix sets every path
            self._set_first_fix(position_m if first_pos else None, heading_rad if first_head else None)
        self.columns.append(_Column(None, win.copy()))
        self.t += 1
        self._since_prune += 1
        if self.prune_every and self._since_prune >= self.prune_every:
            self.prune()

    def _set_first_fix(self, position_m: np.ndarray | None, heading_rad: float | None) -> None:
        """Eq. 5's initial state from the first camera fix, for whichever of position / heading it brings."""
        if position_m is not None:
            if self.track_global:
                self._state[0][:], self._state[1][:] = position_m[0], position_m[1]
            self._pos_known = True
        if heading_rad is not None:
            if self.track_global:
                self._state[2][:] = self._global_state(0j, heading_rad)[2]
            self._head_known = True

    def _warp(self, position_m: np.ndarray | None, heading_rad: float | None) -> None:
        """Pull every path's new root towards this sample's camera fix (warp.py), bounded per sample."""
        gp, maxp, gh, maxh = self.warp.per_sample(self.graph.config.fps)
        if position_m is None:
            gp = maxp = np.float32(0.0)
        if heading_rad is None:
            gh = maxh = np.float32(0.0)
        mpos = np.zeros(2) if position_m is None else np.asarray(position_m, float)
        mh = np.float32(wrap_angle(heading_rad)) if heading_rad is not None else np.float32(0.0)
        args = (*self._state, np.float32(mpos[0]), np.float32(mpos[1]), mh, gp, maxp, gh, maxh)
        self.kernels.warp_state(*args)

    def _record_fix(self, position_m, heading_rad, reset: bool) -> None:
        """Keep this sample's camera fix (None where missing) for the output replay; `reset`: the first fix of a
        take that started without one (every path is set to it)."""
        pos = None if position_m is None or np.any(np.isnan(position_m)) else complex(position_m[0], position_m[1])
        head = None if heading_rad is None or np.isnan(heading_rad) else float(heading_rad)
        self._fixes.append((pos, head, reset))

    def _node_terms(self, mpos: np.ndarray, mhead: float) -> None:
        """Into `_terms`, per node: C, Sn = cos O, sin O; (ux, uz) = R(-O)(P - M); th = wrap(O - M_h); float32
        (see kernels_numpy.node_terms)."""
        mx, mz, mh = np.float32(mpos[0]), np.float32(mpos[1]), np.float32(mhead)
        self.kernels.node_terms(*self._state, mx, mz, mh, *self._terms)

    def reanchor(self, position_m: np.ndarray | None, heading_rad: float | None) -> None:
        """Forget the accumulated costs (every live path starts over at cost 0, so the next samples decide
        afresh) and, with global state, put every path's root on this sample's camera fix. Paths stay graph
        paths: back-pointers are kept, only the evidence before now no longer counts. For the online decoder's
        lost-track recovery (online.FixedLagSynthesizer)."""
        live = np.isfinite(self._G)
        self._G[live] = 0.0
        pos = None if position_m is None or np.any(np.isnan(position_m)) else np.asarray(position_m, float)
        head = None if heading_rad is None or np.isnan(heading_rad) else float(heading_rad)
        if pos is not None or head is not None:
            self._set_first_fix(pos, head)
            if self.warp.active:
                old = self._fixes[-1]
                self._fixes[-1] = (old[0] if pos is None else complex(*pos), old[1] if head is None else head, True)

    # ----- state by graph node ------------------------------------------------------------------
    def cost_of(self, node: int) -> float:
        return float(self._G[node]) + self.cost_offset

    def broken_of(self, node: int) -> int:
        return int(self._Gr[node])

    def best_node(self) -> int:
        """Graph node with the lowest (broken constraints, cost) at the current sample. Every path may have died
        in a dead end (a graph built with --no-connect, or a leave-out that cut a small graph into chains): that
        is reported as `PathsExhaustedError`, never decided from a dead node."""
        if not self.constrained:
            best = int(np.argmin(self._G))
        else:
            fewest = self._Gr == self._Gr.min()
            best = int(np.argmin(np.where(fewest, self._G, np.inf)))
        if not np.isfinite(self._G[best]):
            dead_ends = int(np.count_nonzero(np.bincount(self.graph.edge_src, minlength=self.graph.n_nodes) == 0))
            raise PathsExhaustedError(
                f"every path of the search ended in a dead end by sample {self.t}: the graph ({self.graph.n_nodes} "
                f"nodes, {dead_ends} dead ends) cannot explain a take this long; build it connected (build-graph "
                "without --no-connect) or hold out less of the database")
        return best

    def ancestors(self, k: int, n_steps: int) -> np.ndarray:
        """(n_steps + 1, k) graph nodes: column 0 the best path's (`best_node`), the others the next lowest-cost
        live nodes now; row i = where each of these paths was i samples ago. For the blended output pose
        (SearchWeights.blend_paths): k paths that match the recent samples about equally well, each back-traced
        to the sample being decided."""
        best = self.best_node()
        k = min(k, int(np.isfinite(self._G).sum()))
        G = np.where(self._Gr == self._Gr[best], self._G, np.inf) if self.constrained else self._G.copy()
        G[best] = -np.inf
        top = np.argpartition(G, k - 1)[:k]
        nodes = top[np.argsort(G[top], kind="stable")]
        n_steps = min(n_steps, len(self.columns))
        out = np.empty((n_steps + 1, len(nodes)), dtype=np.int64)
        out[0] = nodes
        for i in range(n_steps):
            col = self.columns[len(self.columns) - 1 - i]
            out[i + 1] = self._graph_src[self.runs.edge_id[self._lookup(col, out[i])]]
        return out

    # ----- path memory --------------------------------------------------------------------------
    def _lookup(self, col: _Column, nodes: np.ndarray) -> np.ndarray:
        """Arriving edge (search index) of each graph node in `nodes` from one column."""
        idx = nodes if col.nodes is None else np.searchsorted(col.nodes, nodes)
        return col.edges[idx].astype(np.intp)

    def _arriving_edge(self, col: _Column, node: int) -> int:
        """Graph edge id that reached `node` in one column."""
        return int(self.runs.edge_id[self._lookup(col, np.array([node]))[0]])

    def prune(self) -> None:
        """Survivor-path memory reduction: keep only lattice entries on some live node's back-trace, walking back
        from the newest column to the first one pruned before against the same set, or pruned when it was
        already PRUNE_HORIZON samples old (its survivors had settled into a few lineages then; walking on to an
        exact match made pruning quadratic in the take length: 4,943 column passes for 720 samples)."""
        self._since_prune = 0
        alive = np.flatnonzero(np.isfinite(self._G))
        mark = np.zeros(self.graph.n_nodes, dtype=bool)
        for k in range(len(self.columns) - 1, -1, -1):
            col = self.columns[k]
            age = self.t - (self.first_column_time + k)
            if col.nodes is not None and (len(col.nodes) == len(alive) or col.pruned_age >= PRUNE_HORIZON):
                break  # (alive is a subset of col.nodes: equal) or pruned when its survivors had settled
            full = col.nodes is None
            edges, sources = self.kernels.survivor_column(alive if full else col.nodes, col.edges, full, alive,
                                                          self._src32, mark)
            self.columns[k] = _Column(alive, edges, age)
            alive = sources

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
            e = self._arriving_edge(col, int(nodes[n_steps - i]))
            edges[n_steps - i] = e
            nodes[n_steps - i - 1] = self._graph_src[e]
        if n_steps < len(self.columns):
            col = self.columns[len(self.columns) - 1 - n_steps]
            edges[0] = self._arriving_edge(col, int(nodes[0]))
        return nodes, edges

    def global_states(self, node: int, edges: np.ndarray,
                      start: tuple[complex, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Ground position (T, 2) and heading (T,) along a back-traced path ending at `node` now.

        With global costs these are the values the search carried, recovered by undoing the path's edges from
        `node`'s current state (never stored per sample); vectorised inverse of eq. 5:
        O[i] = O_end - sum_{m>i} dh_m, P[i] = P_end - sum_{m>i} R(O[m-1]) d_m.
        Without them (Markov search) eq. 5 is integrated forward from `start` = (ground x + iz, heading) of
        the path's first sample (default: the first input sample). With root warping the warped recursion is
        replayed forward from the first input sample (`warped_states`)."""
        if self.warp.active:
            if start is not None or len(edges) != self.t + 1:
                raise ValueError("a warped track from a later sample: call warped_states with its start state")
            return self.warped_states(edges, 0, self.start_state, None)
        e = np.asarray(edges[1:], dtype=np.intp)
        dh = self._graph_dh[e]
        if self.track_global:
            Px, Pz, O = (float(a[node]) for a in self._state)
            heading = O - np.r_[np.cumsum(dh[::-1])[::-1], 0.0]  # minus the dh of later edges
            steps = self._graph_d[e] * np.exp(-1j * heading[:-1])
            ground = complex(Px, Pz) - np.r_[np.cumsum(steps[::-1])[::-1], 0.0]
        else:
            p0, o0 = self.start_state if start is None else start
            heading = o0 + np.r_[0.0, np.cumsum(dh)]
            ground = p0 + np.r_[0.0, np.cumsum(self._graph_d[e] * np.exp(-1j * heading[:-1]))]
        return np.stack([ground.real, ground.imag], axis=1), wrap_angle(heading)

    def warped_states(self, edges: np.ndarray, time0: int, start: tuple[complex, float],
                      first_row: int | None) -> tuple[np.ndarray, np.ndarray]:
        """Ground (T, 2) and heading (T,) of a path whose samples time0 .. time0 + T - 1 arrive by `edges`, with
        root warping replayed (float64) from `start`: the state *before* sample time0 if `first_row` (the metadata
        row of the step into time0) is given, else the state *at* time0 (the first input sample)."""
        g = self.graph
        rows = g.edge_meta[np.maximum(np.asarray(edges), 0)]
        if first_row is not None:
            rows[0] = first_row
        fixes = self._fixes[time0 - self.first_fix_time:time0 - self.first_fix_time + len(edges)]
        pos = np.array([[np.nan, np.nan] if f[0] is None else [f[0].real, f[0].imag] for f in fixes]).reshape(-1, 2)
        head = np.array([np.nan if f[1] is None else f[1] for f in fixes])
        return follow_camera(g.meta_dpos_m[rows], g.meta_dheading_rad[rows], start, pos, head, self.warp,
                             g.config.fps, reset=np.array([f[2] for f in fixes], dtype=bool),
                             step_first=first_row is not None)

    def drop_before(self, time: int) -> None:
        """Forget columns of samples earlier than `time` (already emitted by a fixed-lag decoder)."""
        n_drop = max(0, min(len(self.columns), time - self.first_column_time))
        if n_drop:
            del self.columns[:n_drop]
            self.first_column_time += n_drop
        n_fix = max(0, min(len(self._fixes), time - self.first_fix_time))
        if n_fix:
            del self._fixes[:n_fix]
            self.first_fix_time += n_fix


def constraint_penalties(constraints: list[Constraint], n_nodes: int, n_samples: int) -> dict[int, np.ndarray]:
    """Per-sample broken-constraint counts C_r(n, t) (only samples with an active constraint appear)."""
    out: dict[int, np.ndarray] = {}
    for c in constraints:
        if c.node_mask.shape != (n_nodes,):
            raise ValueError(f"constraint mask has shape {c.node_mask.shape}, graph has {n_nodes} nodes")
        for t in range(max(0, c.frame - c.tolerance_frames), min(n_samples, c.frame + c.tolerance_frames + 1)):
            out[t] = out.get(t, np.zeros(n_nodes)) + (~c.node_mask)
    return out


def observation(obs: Observations, t: int) -> tuple[np.ndarray | None, np.ndarray | None, float | None]:
    """Sample t of `obs` as the search consumes it: (acc or None, position or None, heading or None)."""
    # a NaN acc row is a sensor dropout (engine.stream marks them): step on the camera alone
    acc = None if obs.acc_g is None or np.isnan(obs.acc_g[t]).any() else obs.acc_g[t]
    pos = None if obs.position_m is None else obs.position_m[t]
    head = None if obs.heading_rad is None else float(obs.heading_rad[t])
    return acc, pos, head


def viterbi_search(graph: MotionGraph, weights: SearchWeights, obs: Observations,
                   constraints: list[Constraint] | None = None, prune_every: int = PRUNE_EVERY,
                   kernel: str = DEFAULT_KERNEL, warp: RootWarp = RootWarp.off()) -> SearchResult:
    """Seed 000's batch search: every sample stepped, then the best final path back-traced. (A forgetting search
    decides sample by sample instead: `engine.graph.search.ViterbiSearch` chooses.)"""
    lattice = ViterbiLattice(graph, weights, obs.sensor_indices, prune_every, kernel, warp,
                             obs.orientation_calibration)
    for step in step_arguments(lattice, obs, constraints):
        lattice.step(*step[:5], quat_wxyz=step[5])
    return finish(lattice)


def step_arguments(lattice: ViterbiLattice, obs: Observations, constraints: list[Constraint] | None = None):
    """Per sample of `obs`, the arguments of `lattice.step` (acc, position, heading, constraint penalty, C_A row,
    orientations). The accelerometer rows are computed `ACC_BATCH` samples at a time (compiled: in one pass over
    the metadata; identical per row either way), so every whole-take caller -- the batch search and the forgetting
    search's fixed-lag replay -- steps bit for bit alike. Lazy: each batch is computed just before its first
    sample. With orientations the rows are computed as each sample steps (the orientation features depend on the
    samples decided so far: orientation_term.py), identical per row again."""
    penalties = constraint_penalties(constraints or [], lattice.graph.n_nodes, obs.n_samples)
    quats = obs.quat_wxyz if lattice.orientation is not None else None
    batch = obs.acc_g is not None and lattice.n_sensors and lattice.weights.acc != 0 and lattice.orientation is None
    rows = None
    for t in progress.bar(range(obs.n_samples), desc="search", unit="sample"):
        if batch and t % ACC_BATCH == 0:
            rows = lattice.acc_rows_batch(obs.acc_g[t:t + ACC_BATCH])
        acc, pos, head = observation(obs, t)
        yield (acc, pos, head, penalties.get(t), rows[t % ACC_BATCH] if batch and t and acc is not None else None,
               None if quats is None else quats[t])


def finish(lattice: ViterbiLattice) -> SearchResult:
    """Back-trace the best path from the current state of the lattice (end of the sequence)."""
    lattice.prune()
    best = lattice.best_node()
    nodes, edges = lattice.backtrace(best, len(lattice.columns))
    ground, heading = lattice.global_states(best, edges)
    return SearchResult(nodes=nodes, edges=edges, ground_m=ground, heading_rad=heading,
                        cost=lattice.cost_of(best), broken_constraints=lattice.broken_of(best),
                        compression_ratio=lattice.compression_ratio(), lattice_entries=lattice.lattice_entries())
