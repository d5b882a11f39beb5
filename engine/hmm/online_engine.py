"""The hierarchical HMM in the engine registry (`engine.stream.registry`): its spec, database builder (models
trained on clips) and `OnlineEngine` adapter.

The seed's HMM reads accelerometer + gyroscope. A live stream may carry accelerations only (the design card's
stations), or also angular rate and orientation (issue 18: x-IMU3, Shimmer3, emulated orientation stations). So
the spec holds one model per channel set -- accelerometer only (always), acc + gyro (the paper's) and acc + gyro
+ tilt -- and each session runs the richest one its first complete frame can feed (`HMMEngine.channels`).
The HMM has no database file: ``load_spec`` is None and the console refuses --graph/--kb for it."""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from engine.stream.decided import decided_pose
from engine.stream.engines import ACC, GYRO, ORIENTATION, EngineMismatchError, EnginePose, EngineSpec

if TYPE_CHECKING:
    from engine.graph.warp import RootWarp

DEFAULT_IMUS = ("right_foot",)  # seed 004's one IMU
RICHER_CHANNELS = ("acc+gyro+tilt", "acc+gyro")  # tried in this order when the stream brings them
load_spec = None


def _fed(channels: str, gyro: bool, orientation: bool) -> bool:
    """Can a frame with (gyro, orientation) present feed a model on ``channels``?"""
    parts = channels.split("+")
    return ("gyro" not in parts or gyro) and ("tilt" not in parts or orientation)


class HMMEngine:
    """`engine.hmm.HMMReconstructor` in the `OnlineEngine` protocol. ``models`` maps `HMMConfig.imu_channels` to
    a trained model; the first complete frame picks the richest model it can feed (module doc; "acc" when the
    frame brings neither gyro nor orientation) for the whole session. Each frame is decided at once (no lag): its
    body features are decoded incrementally -- root ground step and heading change integrated from the first
    frame, standing at the origin facing +z, as `engine.hmm.features.decode` does for a whole take -- and the pose
    is that root and those local joint rotations of ``skeleton``, its joints their forward kinematics
    (`engine.stream.decided`), so the console, the poses file and the BVH file show one pose.

    A camera fix pulls the integrated root towards it after every frame by the bounded root warp
    (engine/graph/warp.py; the first fix places the root), exactly as the batch `engine.hmm.evaluation.reconstruct`
    does, so a take gives the same root live and offline; the heading fix is where the hips face, read off this
    frame's pose. A dropout frame is the reconstructor's own rule (no evidence: the chains move on their
    transitions); nothing is emitted before the first complete reading."""

    def __init__(self, models: Mapping[str, Any], skeleton: Any, root_warp: RootWarp | None = None) -> None:
        from engine.graph.warp import RootWarp
        from engine.mocap import joint_roles

        self.models = dict(models)
        self.skeleton = skeleton
        self.root_warp = RootWarp() if root_warp is None else root_warp
        self.n_sensors = next(iter(self.models.values())).imu_mean.shape[0] // 3
        roles = joint_roles(skeleton)
        self._hips = (roles["left_hip"], roles["right_hip"])
        self.rec: Any = None             # the session's HMMReconstructor, once the first frame chose its model
        self.t = -1
        self._ground: complex | None = None  # root on the ground (x + iz) m, None before the first emitted frame
        self._heading = 0.0              # integrated root heading rad
        self._fixed = False              # has a camera fix placed the root yet?

    @property
    def channels(self) -> str | None:
        """The session's model channels (`HMMConfig.imu_channels`), None before the first frame."""
        return None if self.rec is None else self.rec.model.config.imu_channels

    def _start(self, quat_wxyz: np.ndarray | None, gyro_rps: np.ndarray | None) -> None:
        from .reconstructor import HMMReconstructor

        gyro = gyro_rps is not None and bool(np.all(np.isfinite(gyro_rps)))
        orientation = quat_wxyz is not None and bool(np.all(np.isfinite(quat_wxyz)))
        fed = [c for c in RICHER_CHANNELS + ("acc",) if c in self.models and _fed(c, gyro, orientation)]
        # no model the frame can feed (`courtside reconstruct`'s one acc + gyro model): the first, its missing
        # channel a dropout
        self.rec = HMMReconstructor(self.models[fed[0] if fed else next(iter(self.models))])

    def push(self, acc_g: np.ndarray | None, pos_m: Any = None, heading_rad: float | None = None, *,
             quat_wxyz: np.ndarray | None = None, gyro_rps: np.ndarray | None = None) -> list[EnginePose]:
        self.t += 1
        if acc_g is None and self._ground is None:
            return []
        if self.rec is None:
            self._start(quat_wxyz, gyro_rps)
        reading = np.full((self.n_sensors, 3), np.nan) if acc_g is None else np.asarray(acc_g, float)
        # a channel the session's model reads but this frame lacks is a dropped frame for the model (NaN)
        gyro = np.full((self.n_sensors, 3), np.nan) if gyro_rps is None else gyro_rps
        quats = np.full((self.n_sensors, 4), np.nan) if quat_wxyz is None else quat_wxyz
        body = self.rec.push(reading, gyro, quats).body
        step = body[self.skeleton.n_joints * 4: self.skeleton.n_joints * 4 + 3]
        if self._ground is None:
            self._ground = 0j
        else:
            self._ground += complex(step[0], step[2]) * np.exp(-1j * self._heading)
            self._heading += float(body[-1])
        self._follow_camera(body, pos_m, heading_rad)
        root, rotations = self._pose(body, self._heading)
        return [decided_pose(self.skeleton, self.t, root, rotations)]

    def _pose(self, body: np.ndarray, heading_rad: float) -> tuple[np.ndarray, np.ndarray]:
        """Root (3,) m at the current ground position and local rotations (J, 4) of ``body`` at this heading."""
        from .features import decode

        roots, rotations = decode(body[None], self.skeleton.n_joints,
                                  np.array([self._ground.real, 0.0, self._ground.imag]), heading_rad)
        return roots[0], rotations[0]

    def _follow_camera(self, body: np.ndarray, pos_m: Any, heading_rad: float | None) -> None:
        """Pull the root towards this frame's camera fix (`engine.graph.warp.follow_camera`'s rule, one frame)."""
        from engine.graph.warp import warp_one
        from engine.mocap import heading_from_positions

        pos = None if pos_m is None or np.any(np.isnan(pos_m)) else complex(pos_m[0], pos_m[1])
        head = None if heading_rad is None or np.isnan(heading_rad) else float(heading_rad)
        if pos is None and head is None:
            return
        offset = 0.0  # where the hips face minus the root's integrated twist
        if head is not None:
            joints = decided_pose(self.skeleton, self.t, *self._pose(body, 0.0)).joint_positions_m
            offset = float(heading_from_positions(joints[None], *self._hips)[0])
        if not self._fixed:
            self._ground = pos if pos is not None else self._ground
            self._heading = head - offset if head is not None else self._heading
            self._fixed = True
            return
        self._ground, body_heading = warp_one(self._ground, self._heading + offset, pos, head, self.root_warp,
                                              self.rec.model.fps)
        self._heading = body_heading - offset

    def flush(self) -> list[EnginePose]:
        return []


def hmm_spec(model: Any, database: str, sensor_names: Sequence[str], skeleton: Any,
             richer: Sequence[Any] = ()) -> EngineSpec:
    """The hierarchical HMM live: ``model`` trained on accelerometers only (what every stream can feed; a model
    that needs more is refused here, with the reason) plus ``richer`` models on more channels, used when the
    stream brings them (see `HMMEngine`). ``inputs`` names every channel some model reads."""
    if model.config.imu_channels != "acc":
        raise EngineMismatchError(f"{database}: this HMM was trained on {model.config.imu_channels} readings; a "
                                  "live stream may carry accelerometers only (train it with imu_channels='acc', "
                                  "and pass richer models beside it)")
    n = model.imu_mean.shape[0] // 3
    if len(sensor_names) != n:
        raise EngineMismatchError(f"{database}: HMM has {n} IMU(s), named {list(sensor_names)}")
    models = {"acc": model, **{m.config.imu_channels: m for m in richer}}
    parts = {p for channels in models for p in channels.split("+")}
    inputs = (ACC,) + ((ORIENTATION,) if "tilt" in parts else ()) + ((GYRO,) if "gyro" in parts else ())
    return EngineSpec("hmm", database, tuple(sensor_names), float(model.fps), np.asarray(skeleton.parents),
                      lambda lag_s: HMMEngine(models, skeleton), lag_applies=False, skeleton=skeleton, inputs=inputs)


def build_spec(motions: Sequence[Any], database: str, sensor_names: Sequence[str] = DEFAULT_IMUS) -> EngineSpec:
    """The HMM trained on ``motions`` at ``sensor_names``: the accelerometer-only model and the richer ones (module
    doc); each trains in a fraction of a second on the shipped clips."""
    from .config import HMMConfig
    from .evaluation import train_model

    model, *richer = [train_model(list(motions), tuple(sensor_names), config=HMMConfig(imu_channels=channels))
                      for channels in ("acc",) + RICHER_CHANNELS]
    return hmm_spec(model, database, sensor_names, motions[0].skeleton, richer)


def shipped_spec(exclude: Sequence[str] = (), calibration: Any = None,
                 sensor_names: Sequence[str] | None = None) -> EngineSpec:
    """The HMM on the shipped subject-16 clips at ``sensor_names``, else the placement a calibration record
    assigns its one live sensor to, else the right foot (seed 004's)."""
    from engine.stream.databases import shipped_motions

    if sensor_names is None:
        worn = tuple(calibration.sensor_ids) if calibration is not None else ()  # segment -> live sensor
        sensor_names = worn if len(worn) == 1 else DEFAULT_IMUS
    return build_spec(shipped_motions(exclude), "shipped CMU clips", sensor_names)
