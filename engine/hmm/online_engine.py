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
    body features are decoded by `engine.hmm.pose_decoder.PoseDecoder` -- the batch reconstruction's decoder, so a
    take gives the same poses live and offline, camera warp included -- standing at the origin facing +z on the
    first frame. The pose is that root and those local joint rotations of ``skeleton``, its joints their forward
    kinematics (`engine.stream.decided`), so the console, the poses file and the BVH file show one pose. A dropout
    frame is the reconstructor's own rule (no evidence: the chains move on their transitions); nothing is emitted
    before the first complete reading."""

    def __init__(self, models: Mapping[str, Any], skeleton: Any, root_warp: RootWarp | None = None) -> None:
        from .features import IMU_CHANNELS

        self.models = dict(models)
        self.skeleton = skeleton
        self.root_warp = root_warp
        channels, model = next(iter(self.models.items()))
        self.n_sensors = model.imu_mean.shape[0] // IMU_CHANNELS[channels]
        self.rec: Any = None             # the session's HMMReconstructor, once the first frame chose its model
        self.decoder: Any = None         # ... and its PoseDecoder
        self.t = -1

    @property
    def channels(self) -> str | None:
        """The session's model channels (`HMMConfig.imu_channels`), None before the first frame."""
        return None if self.rec is None else self.rec.model.config.imu_channels

    def _start(self, quat_wxyz: np.ndarray | None, gyro_rps: np.ndarray | None) -> None:
        from .pose_decoder import PoseDecoder
        from .reconstructor import HMMReconstructor

        gyro = gyro_rps is not None and bool(np.all(np.isfinite(gyro_rps)))
        orientation = quat_wxyz is not None and bool(np.all(np.isfinite(quat_wxyz)))
        fed = [c for c in RICHER_CHANNELS + ("acc",) if c in self.models and _fed(c, gyro, orientation)]
        # no model the frame can feed (`courtside reconstruct`'s one acc + gyro model): the first, its missing
        # channel a dropout
        self.rec = HMMReconstructor(self.models[fed[0] if fed else next(iter(self.models))])
        self.decoder = PoseDecoder(self.skeleton.n_joints, self.rec.model.fps, self.root_warp, self.skeleton)

    def push(self, acc_g: np.ndarray | None, pos_m: Any = None, heading_rad: float | None = None, *,
             quat_wxyz: np.ndarray | None = None, gyro_rps: np.ndarray | None = None) -> list[EnginePose]:
        self.t += 1
        if acc_g is None and self.rec is None:
            return []
        if self.rec is None:
            self._start(quat_wxyz, gyro_rps)
        reading = np.full((self.n_sensors, 3), np.nan) if acc_g is None else np.asarray(acc_g, float)
        # a channel the session's model reads but this frame lacks is a dropped frame for the model (NaN)
        gyro = np.full((self.n_sensors, 3), np.nan) if gyro_rps is None else gyro_rps
        quats = np.full((self.n_sensors, 4), np.nan) if quat_wxyz is None else quat_wxyz
        body = self.rec.push(reading, gyro, quats).body
        return [decided_pose(self.skeleton, self.t, *self.decoder.step(body, pos_m, heading_rad))]

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
