"""A fourth engine as small as the registry allows (`test_registry.py` registers it with one line): the adapter
functions of `engine.stream.registry` and an `OnlineEngine`. Its poses are known exactly from its inputs, so
every driver's plumbing can be checked against them: the training clips' first pose (root-relative), the root on
the camera fix of the frame (else the last fix, else the origin) at the height of sensor 0's x acceleration."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from engine.mocap import forward_kinematics
from engine.stream import EnginePose, EngineSpec
from engine.stream.databases import shipped_motions

SENSORS = ("left_forearm", "right_forearm")
load_spec = None  # no database file


class ToyEngine:
    def __init__(self, pose_m: np.ndarray) -> None:
        self.pose_m = pose_m
        self.root_m = np.zeros(3)
        self.t = -1

    def push(self, acc_g: np.ndarray | None, pos_m: Any = None, heading_rad: float | None = None, *,
             quat_wxyz: np.ndarray | None = None, gyro_rps: np.ndarray | None = None) -> list[EnginePose]:
        self.t += 1
        if pos_m is not None:
            self.root_m[[0, 2]] = pos_m
        if acc_g is not None:
            self.root_m[1] = acc_g[0, 0]
        return [EnginePose(self.t, self.pose_m + self.root_m)]

    def flush(self) -> list[EnginePose]:
        return []


def build_spec(motions: Sequence[Any], database: str) -> EngineSpec:
    positions, _ = forward_kinematics(motions[0].slice(0, 1))
    pose = positions[0] - positions[0, :1]
    return EngineSpec("toy", database, SENSORS, float(motions[0].fps), np.asarray(motions[0].skeleton.parents),
                      lambda lag_s: ToyEngine(pose), lag_applies=False, skeleton=motions[0].skeleton)


def shipped_spec(exclude: Sequence[str] = (), calibration: Any = None) -> EngineSpec:
    return build_spec(shipped_motions(exclude)[:1], "shipped CMU clips")
