"""OLNG in the engine registry (`engine.stream.registry`): its spec, database builder (a knowledge base) and
`OnlineEngine` adapter."""
from __future__ import annotations

import time
from dataclasses import replace
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from engine.stream.decided import decided_pose
from engine.stream.engines import EngineMismatchError, EnginePose, EngineSpec

if TYPE_CHECKING:
    from .config import OLNGConfig


class OLNGEngine:
    """`engine.olng.OLNGReconstructor` in the `OnlineEngine` protocol. It decides each frame at once (no lag), its
    integrated root follows the camera fix when there is one; a dropout frame holds the last reading (the
    reconstructor's own rule), and nothing is emitted until the first complete reading. It searches on the
    orientation (tilt, relative yaw) and angular rate too when the first frame brings them and the knowledge base
    holds them (`engine.olng.channels`; `channels` says which it uses).

    K and I are sized to the knowledge base (`NeighbourhoodGraphConfig.sized_for`: the paper's K 4096 is for
    500k frames). ``keep_up`` (live use only: the console): the engine times itself and steps down to fewer
    neighbours, hypotheses and energy iterations when a frame costs more than half a frame period
    (`engine.olng.keep_up`); `status` then says so. Offline runs keep it off, so their results do not depend on
    the machine. ``config``: the reconstructor's settings (`courtside reconstruct --k/--i-best/--window`); None =
    the defaults sized to the knowledge base.

    Each emitted pose is the reconstructor's root and local joint rotations on the knowledge base's standard
    skeleton (`skeleton`), its joints their forward kinematics (`engine.stream.decided`): the console, the poses
    file and the BVH file show one pose."""

    def __init__(self, kb: Any, keep_up: bool = False, config: OLNGConfig | None = None) -> None:
        from .config import OLNGConfig
        from .keep_up import Effort, KeepUp, effort_levels
        from .mocap_bridge import skeleton_from_rig
        from .reconstructor import OLNGReconstructor

        if config is None:
            config = OLNGConfig()
            config = replace(config, graph=config.graph.sized_for(kb.size))
        self.rec = OLNGReconstructor(kb, config)
        self.skeleton = skeleton_from_rig(kb.rig)
        self.n_sensors = kb.alpha_g.shape[1] // 3
        self.t = -1
        self.started = False
        start = Effort(config.graph.k_neighbours, config.graph.i_best, config.energy.max_iterations)
        self.keep_up = KeepUp(effort_levels(start), 1.0 / kb.fps) if keep_up else None

    @property
    def channels(self) -> tuple[str, ...] | None:
        """The channels searched on (None until the first frame fixes them)."""
        return self.rec.channels

    @property
    def status(self) -> str:
        """"" normally; a cheaper setting chosen to keep up with the stream, named (one status-bar line)."""
        return "" if self.keep_up is None or not self.keep_up.status else f"olng {self.keep_up.status}"

    def push(self, acc_g: np.ndarray | None, pos_m: Any = None, heading_rad: float | None = None, *,
             quat_wxyz: np.ndarray | None = None, gyro_rps: np.ndarray | None = None) -> list[EnginePose]:
        self.t += 1
        if acc_g is None and not self.started:
            return []
        self.started = True
        reading = np.full((self.n_sensors, 3), np.nan) if acc_g is None else acc_g
        t0 = time.perf_counter()
        pose = self.rec.push(reading, pos_m, heading_rad, quat_wxyz=quat_wxyz, gyro_rps=gyro_rps)
        if self.keep_up is not None and self.keep_up.record(time.perf_counter() - t0):
            effort = self.keep_up.effort
            self.rec.set_effort(effort.k_neighbours, effort.i_best, effort.iterations)
        return [decided_pose(self.skeleton, self.t, pose.root_pos_m, pose.local_quats)]

    def flush(self) -> list[EnginePose]:
        return []


def olng_spec(kb: Any, database: str | Path, sensor_names: Sequence[str] | None = None) -> EngineSpec:
    """OLNG over a knowledge base (`courtside reconstruct --save-kb`, or built from the shipped clips). A saved
    knowledge base does not name its sensors; it is built at the seed-003 placements unless told otherwise.
    ``inputs``: the channels the knowledge base can search on (a stream without orientations runs on acc alone);
    ``make_live``: the console's engine, which keeps up with the stream (`OLNGEngine` keep_up)."""
    from engine.mocap import SEED003_SENSORS

    from .mocap_bridge import skeleton_from_rig

    names = tuple(sensor_names or SEED003_SENSORS)
    n = kb.alpha_g.shape[1] // 3
    if len(names) != n:
        raise EngineMismatchError(f"{database}: knowledge base has {n} sensors, named {list(names)}")
    skeleton = skeleton_from_rig(kb.rig)
    return EngineSpec("olng", str(database), names, float(kb.fps), np.asarray(skeleton.parents),
                      lambda lag_s: OLNGEngine(kb), lag_applies=False, skeleton=skeleton, inputs=kb.channels,
                      make_live=lambda lag_s: OLNGEngine(kb, keep_up=True))


def build_spec(motions: Sequence[Any], database: str) -> EngineSpec:
    """OLNG on a knowledge base built from ``motions`` (about a second for the shipped clips; not cached)."""
    from .config import KnowledgeBaseConfig
    from .mocap_bridge import build_knowledge_base

    return olng_spec(build_knowledge_base(list(motions), KnowledgeBaseConfig()), database)


def shipped_spec(exclude: Sequence[str] = (), calibration: Any = None) -> EngineSpec:
    """OLNG on the shipped subject-16 clips (the knowledge base's sensors are the seed-003 placements; a
    calibration record does not change them)."""
    from engine.stream.databases import shipped_motions

    return build_spec(shipped_motions(exclude), "shipped CMU clips")


# A saved knowledge base keeps the virtual sensors it was built with.
LOADED_DATABASE_TAKES_CALIBRATION = False


def load_spec(path: str | Path, calibration: Any = None) -> EngineSpec:
    """OLNG on a knowledge base saved by `courtside reconstruct --save-kb` (a calibration record does not change
    it)."""
    from .knowledge_base import KnowledgeBase

    return olng_spec(KnowledgeBase.load(path), path)
