"""The engine protocol every synthesis engine is driven through, and the checks that go with it.

`EngineSpec` names the engine and its database (shown in the console's status bar and saved with the poses),
the worn placements in the engine's sensor-column order, its frame rate, the channels it uses (``inputs``), the
skeleton of its poses, and makes a fresh `OnlineEngine` for a given lag. `check_live_sensors` refuses a database
that does not fit the live sensors (count, placement names, rate) with a message that names both sides.
`drive_frames` is the one push loop over frames already on the clock (a synthesis-input take, an evaluation
take): the live path (`engine.stream.session`) pushes the same way, frame by frame.

Which engines exist is `engine.stream.registry`; each engine package exports its own spec, database builder and
`OnlineEngine` adapter (`engine/graph/online_engine.py`, `engine/olng/online_engine.py`,
`engine/hmm/online_engine.py`).

Default engine by the number of worn sensors (`default_engine`): 4 -> ``olng`` (Tautges et al.'s OLNG is built for
wrists + ankles), 1 -> ``hmm`` (the hierarchical HMM is built for one foot IMU), anything else -> ``motion-graph``
(1-6 sensors plus the camera)."""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from engine import progress
from engine.errors import CourtsideError

ACC, ORIENTATION, GYRO = "acc", "orientation", "gyro"  # the channel names of `EngineSpec.inputs`


class EngineMismatchError(CourtsideError):
    """The chosen engine/database cannot run on the live sensors (the message says why)."""


class SensorsMissingError(EngineMismatchError):
    """Sensors the engine needs are not (yet) streaming."""


class OnlineEngine(Protocol):
    """What every driver pushes: one frame per `push` (acc (S, 3) g or None for a dropout, court position (2,) m
    or None, heading rad or None, and by keyword the sensors' orientation ``quat_wxyz`` (S, 4) sensor -> device
    earth (Z up, yaw per sensor) and angular rate ``gyro_rps`` (S, 3) rad/s, None when not streamed, NaN rows
    where invalid); an engine that cannot use a channel ignores it. Returns decided poses, each with ``t``
    (0-based push index) and ``joint_positions_m`` (J, 3), optionally ``confidence``. `flush` decides what is
    still pending (end of input)."""

    def push(self, acc_g: np.ndarray | None, pos_m: np.ndarray | None = None, heading_rad: float | None = None, *,
             quat_wxyz: np.ndarray | None = None, gyro_rps: np.ndarray | None = None) -> list[Any]: ...

    def flush(self) -> list[Any]: ...


@dataclass
class EngineSpec:
    name: str                       # a name in engine.stream.registry
    database: str                   # what the engine was built from: a file, or "shipped CMU clips (cached ...)"
    sensor_names: tuple[str, ...]   # worn placement of each engine sensor column, in order
    rate_hz: float                  # synthesis frame rate
    parents: np.ndarray             # skeleton parents of the emitted joint positions
    make: Callable[[float], OnlineEngine]  # lag_s -> a fresh OnlineEngine
    lag_applies: bool = True        # False: the engine decides each frame at once (OLNG)
    graph: Any = None               # the motion graph (motion-graph engine): what pose streaming needs
    skeleton: Any = None            # engine.mocap.Skeleton of the emitted poses, when known
    inputs: tuple[str, ...] = (ACC,)  # the channels the engine uses (ACC, ORIENTATION, GYRO)
    inputs_note: str = ""           # how it uses them, shown after them (the motion graph: "calibrated yaw" when
                                    # it poses segments with their yaw relative to the pelvis, else "tilt only")
    make_live: Callable[[float], OnlineEngine] | None = None  # a real-time caller's engine (the console): may trade
                                    # accuracy for time and say so in its `status`; None = `make`
    in_process: bool = False        # its engines use this process's sockets and threads (pose streaming out):
                                    # a caller must not run them in a forked child process

    def live(self, lag_s: float) -> OnlineEngine:
        """A fresh engine for a live stream (`make_live`, else `make`)."""
        return (self.make_live or self.make)(lag_s)

    @property
    def label(self) -> str:
        """One line for a status bar: engine, database, sensors, channels (and how they are used)."""
        note = f" ({self.inputs_note})" if self.inputs_note else ""
        return (f"{self.name} on {self.database} ({len(self.sensor_names)} sensors @ {self.rate_hz:g} Hz, "
                f"{'+'.join(self.inputs)}{note})")


@dataclass(frozen=True)
class EnginePose:
    """A decided pose in the `OnlineEngine` protocol: push index, joints, optional confidence and, for an engine
    whose poses are rotations of `EngineSpec.skeleton`, the pose itself: ``root_m`` (3,) world root position and
    ``local_rotations`` (J, 4) local joint rotations (w, x, y, z). Then ``joint_positions_m`` is their forward
    kinematics (`engine.stream.decided.decided_pose`), so every sink (skeleton view, poses file, BVH file and
    streams, evaluation) shows the same pose."""

    t: int
    joint_positions_m: np.ndarray
    confidence: float | None = None
    root_m: np.ndarray | None = None
    local_rotations: np.ndarray | None = None


def default_engine(n_worn: int) -> str:
    """The engine the number of worn sensors calls for (module doc)."""
    return {4: "olng", 1: "hmm"}.get(n_worn, "motion-graph")


def _row(values: np.ndarray | None, t: int) -> np.ndarray | None:
    """Frame t of an optional per-sensor channel; None when absent or when no sensor has a value (all NaN)."""
    if values is None:
        return None
    row = values[t]
    return None if np.isnan(row).all() else row


def drive_frames(engine: OnlineEngine, acc_g: np.ndarray | None, pos_m: np.ndarray | None = None,
                 heading_rad: np.ndarray | None = None, *, quat_wxyz: np.ndarray | None = None,
                 gyro_rps: np.ndarray | None = None) -> list[Any]:
    """Push every frame of a take already on the frame clock (acc (T, S, 3) g, positions (T, 2) m, headings (T,)
    rad, optional (T, S, 4) / (T, S, 3) channels) and flush: the engine's emitted poses in order. A frame with a
    NaN acceleration (a dropout) is pushed without accelerations, a NaN fix without a fix, as the live path does."""
    given = [a for a in (acc_g, pos_m, heading_rad) if a is not None]
    if not given:
        raise ValueError("drive_frames: no accelerations, positions or headings to push")
    n = len(given[0])
    out: list[Any] = []
    for t in progress.bar(range(n), desc="synthesis", unit="frame"):
        acc = None if acc_g is None or np.isnan(acc_g[t]).any() else acc_g[t]
        pos = None if pos_m is None or np.isnan(pos_m[t]).any() else pos_m[t]
        head = None if heading_rad is None or np.isnan(heading_rad[t]) else float(heading_rad[t])
        out += engine.push(acc, pos, head, quat_wxyz=_row(quat_wxyz, t), gyro_rps=_row(gyro_rps, t))
    return out + engine.flush()


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
