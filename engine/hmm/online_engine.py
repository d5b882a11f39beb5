"""The hierarchical HMM in the engine registry (`engine.stream.registry`): its spec, database builder (a model
trained on clips) and `OnlineEngine` adapter.

The seed's HMM reads accelerometer + gyroscope; the gateway streams accelerometers only, so the live HMM runs a
model trained on accelerometers only (its accuracy against the paper's acc + gyro model is in docs/console.md).
The HMM has no database file: ``load_spec`` is None and the console refuses --graph/--kb for it."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from engine.stream.engines import EngineMismatchError, EnginePose, EngineSpec

DEFAULT_IMUS = ("right_foot",)  # seed 004's one IMU
load_spec = None


class HMMEngine:
    """`engine.hmm.HMMReconstructor` in the `OnlineEngine` protocol, on a model trained on accelerometers only
    (``HMMConfig.imu_channels == "acc"``: the live stream carries no gyroscope; a pushed ``gyro_rps`` is ignored).
    Each frame is decided at once (no lag); the body features are decoded incrementally (root ground step and
    heading change integrated from the first frame, as `engine.hmm.features.decode` does for a whole take) and the
    joints follow by forward kinematics. A camera fix sets the root's ground position for that frame (the stream
    path gives every frame the fix interpolated at its own time); without one the root is integrated from the
    last. A dropout frame is the reconstructor's own rule (no evidence: the chains move on their transitions);
    nothing is emitted before the first complete reading."""

    def __init__(self, model: Any, skeleton: Any) -> None:
        from .reconstructor import HMMReconstructor

        self.rec = HMMReconstructor(model)
        self.skeleton = skeleton
        self.n_sensors = model.imu_mean.shape[0] // 3
        self.t = -1
        self._prev: tuple[np.ndarray, np.ndarray, float] | None = None  # (body features, root m, heading rad)

    def push(self, acc_g: np.ndarray | None, pos_m: Any = None, heading_rad: float | None = None, *,
             quat_wxyz: np.ndarray | None = None, gyro_rps: np.ndarray | None = None) -> list[EnginePose]:
        from engine.mocap import Motion, forward_kinematics

        from .features import decode

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


def build_spec(motions: Sequence[Any], database: str, sensor_names: Sequence[str] = DEFAULT_IMUS) -> EngineSpec:
    """The HMM trained on ``motions`` at ``sensor_names``, accelerometer only (the live stream has no gyroscope);
    trains in a fraction of a second on the shipped clips."""
    from .config import HMMConfig
    from .evaluation import train_model

    model = train_model(list(motions), tuple(sensor_names), config=HMMConfig(imu_channels="acc"))
    return hmm_spec(model, database, sensor_names, motions[0].skeleton)


def shipped_spec(exclude: Sequence[str] = (), calibration: Any = None,
                 sensor_names: Sequence[str] | None = None) -> EngineSpec:
    """The HMM on the shipped subject-16 clips at ``sensor_names``, else the placement a calibration record
    assigns its one live sensor to, else the right foot (seed 004's)."""
    from engine.stream.databases import shipped_motions

    if sensor_names is None:
        worn = tuple(calibration.sensor_ids) if calibration is not None else ()  # segment -> live sensor
        sensor_names = worn if len(worn) == 1 else DEFAULT_IMUS
    return build_spec(shipped_motions(exclude), "shipped CMU clips, accelerometer-only model", sensor_names)
