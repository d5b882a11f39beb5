"""Which synthesis engine runs on which worn sensors, from which database — one description the console and the
offline commands share.

`EngineSpec` names the engine and its database (shown in the console's status bar and saved with the poses),
the worn placements in the engine's sensor-column order, its frame rate, the skeleton of its poses, and makes a
fresh `engine.stream.OnlineEngine` for a given lag. `check_live_sensors` refuses a database that does not fit
the live sensors (count, placement names, rate) with a message that names both sides.

Default engine by the number of worn sensors (`default_engine`): 4 -> ``olng`` (Tautges et al.'s OLNG is built for
wrists + ankles), 1 -> ``hmm`` (the hierarchical HMM is built for one foot IMU), anything else -> ``motion-graph``
(1-6 sensors plus the camera). The seed's HMM reads accelerometer + gyroscope; the gateway streams
accelerometers only, so the live HMM runs a model trained on accelerometers only (`HMMEngine`; its accuracy
against the paper's acc + gyro model is in docs/console.md)."""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import CourtsideError

ENGINE_NAMES = ("motion-graph", "olng", "hmm")


class EngineMismatchError(CourtsideError):
    """The chosen engine/database cannot run on the live sensors (the message says why)."""


class SensorsMissingError(EngineMismatchError):
    """Sensors the engine needs are not (yet) streaming."""


@dataclass
class EngineSpec:
    name: str                       # one of ENGINE_NAMES
    database: str                   # what the engine was built from: a file, or "shipped CMU clips (cached ...)"
    sensor_names: tuple[str, ...]   # worn placement of each engine sensor column, in order
    rate_hz: float                  # synthesis frame rate
    parents: np.ndarray             # skeleton parents of the emitted joint positions
    make: Callable[[float], Any]    # lag_s -> a fresh OnlineEngine
    lag_applies: bool = True        # False: the engine decides each frame at once (OLNG)
    graph: Any = None               # the motion graph (motion-graph engine): what pose streaming needs
    skeleton: Any = None            # engine.mocap.Skeleton of the emitted poses, when known
    inputs: tuple[str, ...] = ("acc",)  # channels the engine uses: "acc", "orientation", "gyro" (status bar)

    @property
    def label(self) -> str:
        """One line for a status bar: engine, database, sensors."""
        return f"{self.name} on {self.database} ({len(self.sensor_names)} sensors @ {self.rate_hz:g} Hz)"


@dataclass(frozen=True)
class EnginePose:
    """A decided pose in the `OnlineEngine` protocol: push index, joints, optional confidence."""

    t: int
    joint_positions_m: np.ndarray
    confidence: float | None = None


def default_engine(n_worn: int) -> str:
    """The engine the number of worn sensors calls for (module doc)."""
    return {4: "olng", 1: "hmm"}.get(n_worn, "motion-graph")


def motion_graph_spec(graph: Any, database: str | Path, skeleton: Any = None, warp: Any = None,
                      fusion: Any = None) -> EngineSpec:
    """Fixed-lag Viterbi over a `engine.graph.MotionGraph` (from `courtside build-graph` or the console's cache),
    with `courtside synthesize`'s defaults: root warping towards the camera (``warp``, default
    `engine.graph.warp.RootWarp()`) and the weights that go with it, the output root fused from the camera track
    (``fusion``, default `engine.graph.root_fusion.RootFusion()`). The confidence reference (the cost per sample
    of the graph's own clips) is measured once here, not at every engine restart."""
    from engine.graph.confidence import reference_cost_per_sample
    from engine.graph.online import FixedLagSynthesizer
    from engine.graph.root_fusion import RootFusion
    from engine.graph.warp import RootWarp, default_weights

    skeleton = graph.skeleton if skeleton is None else skeleton
    if skeleton is None:
        raise EngineMismatchError(f"{database}: the graph holds no skeleton (rebuild it with build-graph)")
    names = tuple(graph.config.sensor_names)
    if len(names) != graph.n_sensors:
        raise EngineMismatchError(f"{database}: graph has {graph.n_sensors} sensor columns but names {list(names)}")
    warp = RootWarp() if warp is None else warp
    fusion = RootFusion() if fusion is None else fusion
    weights = default_weights(warp)
    reference = reference_cost_per_sample(graph, weights, warp)
    return EngineSpec("motion-graph", str(database), names, float(graph.config.fps), np.asarray(skeleton.parents),
                      lambda lag_s: FixedLagSynthesizer(graph, lag_s, weights, warp=warp,
                                                        confidence_reference=reference, fusion=fusion),
                      graph=graph,
                      skeleton=skeleton)


class OLNGEngine:
    """`engine.olng.OLNGReconstructor` in the `OnlineEngine` protocol. It decides each frame at once (no lag), its
    integrated root follows the camera fix when there is one; a dropout frame holds the last reading (the
    reconstructor's own rule), and nothing is emitted until the first complete reading."""

    def __init__(self, kb: Any) -> None:
        from engine.olng.reconstructor import OLNGReconstructor

        self.rec = OLNGReconstructor(kb)
        self.n_sensors = kb.alpha_g.shape[1] // 3
        self.t = -1
        self.started = False

    def push(self, acc_g: np.ndarray | None, pos_m: Any = None, heading_rad: float | None = None) -> list[EnginePose]:
        self.t += 1
        if acc_g is None and not self.started:
            return []
        self.started = True
        reading = np.full((self.n_sensors, 3), np.nan) if acc_g is None else acc_g
        return [EnginePose(self.t, self.rec.push(reading, pos_m, heading_rad).joints_world_m)]

    def flush(self) -> list[EnginePose]:
        return []


def olng_spec(kb: Any, database: str | Path, sensor_names: Sequence[str] | None = None) -> EngineSpec:
    """OLNG over a knowledge base (`courtside reconstruct --save-kb`, or built from the shipped clips). A saved
    knowledge base does not name its sensors; it is built at the seed-003 placements unless told otherwise."""
    from engine.mocap import SEED003_SENSORS
    from engine.olng.mocap_bridge import skeleton_from_rig

    names = tuple(sensor_names or SEED003_SENSORS)
    n = kb.alpha_g.shape[1] // 3
    if len(names) != n:
        raise EngineMismatchError(f"{database}: knowledge base has {n} sensors, named {list(names)}")
    return EngineSpec("olng", str(database), names, float(kb.fps), np.asarray(skeleton_from_rig(kb.rig).parents),
                      lambda lag_s: OLNGEngine(kb), lag_applies=False)


class HMMEngine:
    """`engine.hmm.HMMReconstructor` in the `OnlineEngine` protocol, on a model trained on accelerometers only
    (``HMMConfig.imu_channels == "acc"``: the live stream carries no gyroscope). Each frame is decided at once (no
    lag); the body features are decoded incrementally (root ground step and heading change integrated from the
    first frame, as `engine.hmm.features.decode` does for a whole take) and the joints follow by forward
    kinematics. A camera fix sets the root's ground position for that frame (the stream path gives every frame
    the fix interpolated at its own time); without one the root is integrated from the last. A dropout frame is
    the reconstructor's own rule (no evidence: the chains move on their transitions); nothing is emitted before
    the first complete reading."""

    def __init__(self, model: Any, skeleton: Any) -> None:
        from engine.hmm.reconstructor import HMMReconstructor

        self.rec = HMMReconstructor(model)
        self.skeleton = skeleton
        self.n_sensors = model.imu_mean.shape[0] // 3
        self.t = -1
        self._prev: tuple[np.ndarray, np.ndarray, float] | None = None  # (body features, root m, heading rad)

    def push(self, acc_g: np.ndarray | None, pos_m: Any = None, heading_rad: float | None = None) -> list[EnginePose]:
        from engine.hmm.features import decode
        from engine.mocap import Motion, forward_kinematics

        self.t += 1
        if acc_g is None and self._prev is None:
            return []
        reading = np.full((self.n_sensors, 3), np.nan) if acc_g is None else np.asarray(acc_g, float)
        body = self.rec.push(reading).body
        joints = self.skeleton.n_joints
        if self._prev is None:  # the first frame: standing where the first decode puts it, facing +z
            roots, quats = decode(body[None], joints, np.zeros(3), 0.0)
            heading = 0.0
        else:
            prev_body, prev_root, prev_heading = self._prev
            roots, quats = decode(np.stack([prev_body, body]), joints, prev_root, prev_heading)
            heading = prev_heading + float(body[-1])
        root = roots[-1].copy()
        if pos_m is not None:
            root[[0, 2]] = np.asarray(pos_m, float)[:2]
        self._prev = (body, root, heading)
        positions, _ = forward_kinematics(Motion(self.skeleton, self.rec.model.fps, root[None], quats[-1:]))
        return [EnginePose(self.t, positions[0])]

    def flush(self) -> list[EnginePose]:
        return []


def hmm_spec(model: Any, database: str, sensor_names: Sequence[str], skeleton: Any) -> EngineSpec:
    """The hierarchical HMM live, on an accelerometer-only model (see `HMMEngine`); a model that needs gyroscope
    readings is refused, with the reason."""
    if model.config.imu_channels != "acc":
        raise EngineMismatchError(f"{database}: this HMM was trained on accelerometer + gyroscope readings; the "
                                  "gateway streams accelerometers only (train it with imu_channels='acc')")
    n = model.imu_mean.shape[0] // 3
    if len(sensor_names) != n:
        raise EngineMismatchError(f"{database}: HMM has {n} IMU(s), named {list(sensor_names)}")
    return EngineSpec("hmm", database, tuple(sensor_names), float(model.fps), np.asarray(skeleton.parents),
                      lambda lag_s: HMMEngine(model, skeleton), lag_applies=False, skeleton=skeleton)


def check_live_sensors(spec: EngineSpec, worn: Sequence[str], nominal_hz: Sequence[float]) -> None:
    """Refuse ``spec`` unless the live sensors fit it: ``worn[i]`` is the placement of the live sensor feeding
    column i (same count, same names, in order) and each streams at least at the engine's frame rate
    (``nominal_hz[i]``; 0 = not known yet, not checked) — slower sensors would have to be up-sampled."""
    if len(worn) != len(spec.sensor_names):
        raise EngineMismatchError(f"{spec.name} database {spec.database} expects {len(spec.sensor_names)} sensors "
                                  f"({', '.join(spec.sensor_names)}); {len(worn)} are worn ({', '.join(worn)})")
    wrong = [f"column {i}: database {a!r}, worn {b!r}" for i, (a, b) in enumerate(zip(spec.sensor_names, worn)) if a != b]
    if wrong:
        raise EngineMismatchError(f"{spec.name} database {spec.database} was built for other placements: "
                                  + "; ".join(wrong))
    slow = [f"{name} {hz:g} Hz" for name, hz in zip(worn, nominal_hz) if 0 < hz < spec.rate_hz]
    if slow:
        raise EngineMismatchError(f"{spec.name} database {spec.database} runs at {spec.rate_hz:g} Hz but these "
                                  f"sensors stream slower: {', '.join(slow)}")
