"""The motion graph's orientation term (issue 18): what the worn sensors' orientation quaternions add to C_A.

Why: in slow motion an accelerometer reads gravity, i.e. each segment's tilt, and not where a limb points around
the vertical; a real IMU's orientation carries that. But a magnetometer-free filter has no shared north: each
sensor's yaw is arbitrary and drifts (engine/mocap/orientation.py). So the term has two parts:

* **tilt** (yaw-free, always on): each sensor's up axis in its own frame, from the quaternion -- clean, unlike
  the low-passed accelerations in dynamic motion;
* **heading relative to the pelvis** (the lower_back sensor; its share is `SearchWeights.orientation_heading`,
  default 0 -- measured no better than tilt alone on held-out gestures and worse on chained takes, where the
  offsets learnt from wrong decisions lock the search onto them; docs/engine-evaluation.md): the horizontal components of the sensor's axes in
  the pelvis's heading frame, after removing the sensor's yaw offset. ψ_i = the twist of sensor i's orientation
  about the vertical (q = twist(ψ) * swing; a yaw offset of the device's earth frame adds to ψ exactly), d_i =
  ψ_i - ψ_pelvis. The offset of sensor i is estimated ONLINE from the search's own decisions: the exponentially
  weighted circular mean, over the decided samples, of the observed d_i minus the decided database pose's d_i
  (`OrientationEncoder.learn`), with a memory of ~`OFFSET_TIME_CONSTANT_S` so it follows a filter's slow yaw
  drift. Until `MIN_LEARNED_S` of samples are decided only the tilt part is used. (A prior from the database's
  mean d_i was measured first and made every gesture take worse: the forearms' d_i spread over the whole circle.)

With an N-pose calibration (engine/mocap/orientation_calibration.py: each sensor's yaw offset and strapping
from the still capture) nothing is learnt: the readings are turned into the world first, the offsets are zero
from the first sample, and the heading part's share is `SearchWeights.calibrated_heading` (0.5; measured better
than tilt alone on held-out gestures, where learnt offsets were worse: docs/engine-evaluation.md). The
calibrated readings are then the segments' nominal sensor frames, so a forearm's roll about its bone can be told
from where the bone points, and it is heard only by `SearchWeights.forearm_roll` (default 0: `roll_axis_weights`).

Together the two parts are the 3x3 rotation matrix of yaw(-(ψ_pelvis + offset_i)) * q_i (row 1 = tilt, rows 0
and 2 = heading), so their squared distance is the chordal distance, 4 (1 - cos θ) for a rotation by θ.
Without the pelvis sensor among the worn ones only the tilt part exists.

The features are extra columns of the C_A squared distance (viterbi.ViterbiLattice's metadata matrix gets more
rows in groups of three: acc, then tilt, then heading, so acc-only and acc + tilt are prefixes), scaled by
sqrt(weight x the database's acc variance / its orientation-feature variance) so that at weight 1 neither term
drowns the other. The database side comes from the graph's stored joint rotations (`node_rotations`, in every
saved graph) through the standard sensor placements, per metadata row the orientation of the node it arrives at.
Batch and fixed-lag searches see the same features: the batch search with forgetting *is* the fixed-lag decoder
(online.decide_with_forgetting), and the estimate only ever reads decided samples.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from engine.mocap import quaternions as quat
from engine.mocap.orientation import from_device_earth, twist_yaw, virtual_orientations, yaw_about_up
from engine.mocap.orientation_calibration import OrientationCalibration
from engine.mocap.sensors import standard_placements
from engine.mocap.skeleton import Motion

from .graph import MotionGraph

REFERENCE_SENSOR = "lower_back"
OFFSET_TIME_CONSTANT_S = 30.0  # the yaw-offset estimate's memory: long enough to average out wrongly decided
# poses, short enough to follow a filter's drift (OrientationErrorModel.realistic: 3 deg/min)
MIN_LEARNED_S = 1.0  # decided samples (in seconds) before the heading part is used
UP = np.array([0.0, 1.0, 0.0])


def places_sensors(graph: MotionGraph) -> bool:
    """Can the graph's poses give sensor orientations (joint rotations, a skeleton and named standard sensors)?
    Graphs built from bare clip arrays cannot: they search on accelerations alone."""
    return (graph.node_rotations is not None and graph.node_root_m is not None and graph.skeleton is not None
            and bool(graph.config.sensor_names))


def node_sensor_orientations(graph: MotionGraph) -> np.ndarray:
    """(N, S, 4) sensor -> world quaternions of every node's pose (standard placements of the graph's sensors),
    computed once per graph object (forward kinematics of every node: seconds on a large graph)."""
    cached = graph.__dict__.get("_sensor_orientations")
    if cached is not None:
        return cached
    if not places_sensors(graph):
        raise ValueError("this graph stores no joint rotations or sensor placements: rebuild it to use orientations")
    placements = standard_placements(graph.skeleton, graph.config.sensor_names)
    if graph.sensor_rotations is not None:  # the strapping the graph's virtual sensors were built with
        placements = [replace(p, rotation=r) for p, r in zip(placements, graph.sensor_rotations)]
    motion = Motion(graph.skeleton, graph.config.fps, graph.node_root_m.astype(float),
                    graph.node_rotations.astype(float))
    graph.__dict__["_sensor_orientations"] = out = virtual_orientations(motion, placements)
    return out


def row_nodes(graph: MotionGraph) -> np.ndarray:
    """(M,) a node each metadata row arrives at (-1 for rows no edge or node uses)."""
    out = np.full(len(graph.meta_dheading_rad), -1, dtype=np.int64)
    out[graph.edge_meta] = graph.edge_dst
    out[graph.node_arrival] = np.arange(graph.n_nodes)
    return out


def features(quat_world: np.ndarray, reference: int | None, offset_rad: np.ndarray | None,
             heading_share: float = 1.0, axis_weights: np.ndarray | None = None) -> np.ndarray:
    """(..., K, 3) orientation features of sensor orientations (..., S, 4) in the engine world: the tilt part
    (S rows: each sensor's up axis in its frame), then -- with a `reference` sensor and known per-sensor yaw
    offsets `offset_rad` (S,) -- the heading part (2S rows, see the module docstring) times `heading_share`.
    `axis_weights` (S, 3): each feature's components along the sensor's X, Y, Z axes are scaled by them
    (`roll_axis_weights`); None = all 1."""
    q = np.asarray(quat_world, float)
    w = np.ones((q.shape[-2], 3)) if axis_weights is None else np.asarray(axis_weights, float)
    tilt = quat.rotate(quat.conjugate(q), UP) * w  # (..., S, 3) = row 1 of the matrix below
    if reference is None or offset_rad is None:
        return tilt
    psi_ref = twist_yaw(q[..., reference, :])[..., None]
    mats = quat.to_matrix(quat.multiply(yaw_about_up(-(psi_ref + offset_rad)), q))  # (..., S, 3, 3)
    heading = heading_share * (mats[..., [0, 2], :] * w[:, None, :]).reshape(q.shape[:-2] + (2 * q.shape[-2], 3))
    return np.concatenate([tilt, heading], axis=-2)


def roll_axis_weights(sensor_names: list[str], roll_share: float) -> np.ndarray:
    """(S, 3) `features`' axis weights for calibrated orientations: a forearm sensor's Y and Z axes (its nominal
    frame's X lies along the bone) weigh `roll_share` (`SearchWeights.forearm_roll`, default 0), so the search
    hears where the bone points and its roll about the bone only that much. Why: the roll is the least certain
    part of a forearm's calibrated strap (the athlete's palms in the held pose, where the template's face the body:
    30 deg off cost +1.3 cm on held-out bye, `bench/bench_real_recording.py --forearm-roll-deg`; the pronation a
    sensor near the wrist follows and a database forearm need not), and it is the part the database matches
    worst on a motion it lacks. Gesture sessions, leave one content out, held N-pose (docs/engine-evaluation.md
    "The forearm's roll"), share 1 / 0.5 / 0.25 / 0: 9-axis 4.74 / 4.47 / 4.39 / 4.35 cm, 6-axis 5.08 / - / 4.79 /
    4.76; the shins' twist at 0.5 too made the 9-axis sessions worse (4.47 -> 4.66), so it is the forearms'."""
    weights = np.ones((len(sensor_names), 3))
    weights[[n.endswith("forearm") for n in sensor_names], 1:] = roll_share
    return weights


def scaled_rows(graph: MotionGraph, sensor_indices: list[int], f: np.ndarray, used: np.ndarray,
                weight: float) -> tuple[float, np.ndarray]:
    """Extra C_A features (M, K, 3) of the metadata rows (`used`: the rows a node or edge uses; the others are
    zeroed) -> (scale, (3K, M) float32 rows to append to the lattice's acc metadata), scaled by
    sqrt(weight x the database's acc variance / the features' variance): at weight 1 neither part drowns the
    other."""
    f = f.copy()
    f[~used] = 0.0
    acc = np.asarray(graph.meta_acc_g, float)[:, sensor_indices][used]
    acc_var = acc.reshape(len(acc), -1).var(axis=0).sum()
    f_var = f[used].reshape(int(used.sum()), -1).var(axis=0).sum()
    scale = float(np.sqrt(weight * acc_var / max(f_var, 1e-12)))
    return scale, np.ascontiguousarray((f * scale).astype(np.float32).transpose(1, 2, 0)).reshape(-1, len(f))


class OrientationTerm:
    """The database side of the term for one sensor selection: scaled feature rows (3K, M) float32 to append to
    the lattice's acc metadata, each node's relative yaws, and encoders for observed device-earth quaternions."""

    def __init__(self, graph: MotionGraph, sensor_indices: list[int], weight: float, heading_share: float = 0.0,
                 offset_time_constant_s: float = OFFSET_TIME_CONSTANT_S,
                 calibration: OrientationCalibration | None = None, calibrated_heading_share: float = 0.0,
                 roll_share: float = 1.0) -> None:
        names = [graph.config.sensor_names[i] for i in sensor_indices]
        self.calibration = calibration  # known yaw offsets and strapping: the readings are turned into the world
        if calibration is not None:
            heading_share = calibrated_heading_share
        self.heading_share = heading_share  # 0: the tilt part alone (no reference, nothing to learn)
        self.reference = names.index(REFERENCE_SENSOR) if REFERENCE_SENSOR in names and heading_share > 0 else None
        # calibrated orientations are the segments' nominal frames (a forearm's X along its bone); the device's
        # own frames need not be, so only then is the roll told from the bone's direction
        self.axis_weights = None if calibration is None else roll_axis_weights(names, roll_share)
        self.n_sensors = len(sensor_indices)
        self.alpha = 1.0 / max(1.0, offset_time_constant_s * graph.config.fps)
        self.min_learned = MIN_LEARNED_S * graph.config.fps
        nodes = row_nodes(graph)
        q_nodes = node_sensor_orientations(graph)[:, sensor_indices]
        used = nodes >= 0
        psi = twist_yaw(q_nodes)
        self.node_rel_yaw = psi - psi[:, [self.reference or 0]]  # (N, S) d_i of every node (unused: no reference)
        zero = None if self.reference is None else np.zeros(self.n_sensors)
        f = features(q_nodes[np.where(used, nodes, 0)], self.reference, zero, heading_share,
                     self.axis_weights)  # (M, K, 3)
        self.scale, self.meta_rows_t = scaled_rows(graph, sensor_indices, f, used, weight)

    def encoder(self) -> "OrientationEncoder":
        return OrientationEncoder(self)


class OrientationEncoder:
    """Observed device-earth quaternions -> scaled features, one sample at a time (`push`, in order), with the
    per-sensor yaw-offset estimate as its state, learnt from the decided samples (`learn`)."""

    def __init__(self, term: OrientationTerm) -> None:
        self.term = term
        self.t = -1  # the last sample pushed
        self._sum = np.zeros(term.n_sensors, dtype=complex)  # weighted sum of exp(i (observed - decided d_i))
        self._weight = 0.0  # its weight (decided samples, faded)
        self._observed: dict[int, np.ndarray] = {}  # sample -> observed d_i (S,), until it is decided

    def push(self, quat_device: np.ndarray | None) -> np.ndarray | None:
        """(K, 3) scaled features of one sample's (S, 4) device-earth quaternions (tilt only until the yaw offsets
        are learnt); None if any is missing."""
        self.t += 1
        if quat_device is None:
            return None
        q = np.asarray(quat_device, float)
        if q.shape != (self.term.n_sensors, 4):
            raise ValueError(f"expected {self.term.n_sensors} sensors x 4 quaternion components, got {q.shape}")
        if not np.isfinite(q).all():
            return None
        ref = self.term.reference
        if self.term.calibration is not None:  # offsets known: nothing to learn
            q = self.term.calibration.world(q)
            return features(q, ref, None if ref is None else np.zeros(self.term.n_sensors),
                            self.term.heading_share, self.term.axis_weights) * self.term.scale
        q = from_device_earth(q)
        offset = None
        if ref is not None:
            psi = twist_yaw(q)
            self._observed[self.t] = psi - psi[ref]
            if self._weight >= self.term.min_learned:
                offset = np.angle(self._sum)
                offset[ref] = 0.0
        return features(q, ref, offset, self.term.heading_share) * self.term.scale

    def learn(self, first: int, nodes: np.ndarray) -> None:
        """Samples first.. were decided as database `nodes`: each one's observed minus decided relative yaw joins
        the running offset estimate (the older ones fading)."""
        keep = 1.0 - self.term.alpha
        for k, node in enumerate(np.asarray(nodes, dtype=np.int64)):
            d = self._observed.pop(first + k, None)
            if d is not None:
                self._sum = self._sum * keep + np.exp(1j * (d - self.term.node_rel_yaw[node]))
                self._weight = self._weight * keep + 1.0
        for t in [t for t in self._observed if t < first]:  # samples decided without learning (none normally)
            del self._observed[t]
