"""The poses file (.npz) that `courtside console --save-poses` and `courtside synthesize --save-poses` both write,
so a live session and an offline run of the same take can be compared frame by frame.

Arrays: ``frame`` (F,) int64 frame index on the absolute clock (``t_s = frame / rate_hz``), ``t_s`` (F,) gateway
seconds, ``joint_positions_m`` (F, J, 3) world frame (x, y up, z), ``confidence`` (F,) in [0, 1] (NaN when the
engine reports none), ``parents`` (J,) skeleton; when the engine decides rotations (engine.stream.decided) also
``root_m`` (F, 3) and ``local_rotations`` (F, J, 4) (w, x, y, z), whose forward kinematics the joints are;
``meta_json``: engine, database, lag_s, rate_hz, sensors (live
stream per engine column and its placement), start_frame, and anything else the writer adds."""
from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import MalformedFileError
from engine.safe_load import parse_json

from .decided import has_rotations
from .session import FramePose


@dataclass
class PosesFile:
    frame: np.ndarray
    t_s: np.ndarray
    joint_positions_m: np.ndarray
    confidence: np.ndarray
    parents: np.ndarray
    meta: dict[str, Any]
    root_m: np.ndarray | None = None
    local_rotations: np.ndarray | None = None


def save_poses(path: str | Path, poses: Sequence[FramePose], parents: np.ndarray, meta: dict[str, Any]) -> Path:
    path = Path(path)
    n_joints = len(parents)
    joints = np.stack([p.joint_positions_m for p in poses]) if poses else np.zeros((0, n_joints, 3))
    conf = np.array([np.nan if p.confidence is None else p.confidence for p in poses], float)
    rotations = {}
    if has_rotations(poses):
        rotations = {"root_m": np.stack([p.root_m for p in poses]).astype(float),
                     "local_rotations": np.stack([p.local_rotations for p in poses]).astype(float)}
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, frame=np.array([p.frame for p in poses], np.int64),
                        t_s=np.array([p.t_s for p in poses], float), joint_positions_m=joints, confidence=conf,
                        parents=np.asarray(parents), meta_json=np.array(json.dumps(meta)), **rotations)
    return path


def load_poses(path: str | Path) -> PosesFile:
    try:
        with np.load(path, allow_pickle=False) as data:
            missing = [k for k in ("frame", "t_s", "joint_positions_m", "confidence", "parents", "meta_json")
                       if k not in data.files]
            if missing:
                raise MalformedFileError(path, None, f"not a poses file: missing {', '.join(missing)}")
            rotations = [data[k] if k in data.files else None for k in ("root_m", "local_rotations")]
            return PosesFile(data["frame"], data["t_s"], data["joint_positions_m"], data["confidence"],
                             data["parents"], parse_json(str(data["meta_json"]), f"{path}: 'meta_json'"), *rotations)
    except (OSError, ValueError) as exc:
        raise MalformedFileError(path, None, f"not a readable poses .npz ({exc})") from exc
