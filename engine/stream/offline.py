"""Offline synthesis of a recorded take by any registered engine — the same path as live.

A gateway export goes through `synthesize_streams` (sample by sample, the console's own path); a
synthesis-input take (frames already on the clock) through `drive_take`, the one push loop
(`engine.stream.drive_frames`) with each emitted pose placed on the take's frames. `courtside synthesize` uses
both for the motion graph and, with ``--engine``, for every other engine."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import MalformedFileError

from .engines import EngineSpec, OnlineEngine, drive_frames
from .session import FramePose, synthesize_streams


def acc_in_sensor_order(path: str | Path, obs: Any, n_sensors: int, need: str) -> np.ndarray:
    """A take's acc columns (`engine.graph.viterbi.Observations`) in the engine's sensor order (a take may list
    its sensors in any order); a take without all ``n_sensors`` is refused with ``need`` as the reason."""
    indices = tuple(obs.sensor_indices) if obs.sensor_indices is not None else tuple(range(n_sensors))
    if obs.acc_g is None or sorted(indices) != list(range(n_sensors)):
        raise MalformedFileError(path, None, need)
    return obs.acc_g[:, np.argsort(indices)]


def drive_take(engine: OnlineEngine, acc_g: np.ndarray | None, obs: Any, first_frame: int, rate_hz: float
               ) -> list[FramePose]:
    """Every frame of a take on the frame clock pushed (acc (T, S, 3) g in the engine's column order, the
    observations' camera fixes and, when the take has them, orientations and angular rates in the same column
    order), flushed, each pose at its frame ``first_frame + t``."""
    order = np.argsort(obs.sensor_indices) if obs.sensor_indices is not None else slice(None)
    channels = {name: None if getattr(obs, name, None) is None else getattr(obs, name)[:, order]
                for name in ("quat_wxyz", "gyro_rps")}
    return [FramePose.of(first_frame + q.t, rate_hz, q) for q in drive_frames(engine, acc_g, obs.position_m, obs.heading_rad, **channels)]


def synthesize_take(spec: EngineSpec, path: str | Path, lag_s: float, *, sensor_map: dict[str, str] | None = None,
                    use_camera_heading: bool = False, times: str = "t_host_s", start_s: float | None = None
                    ) -> list[FramePose]:
    """The poses ``spec``'s engine decides for the take at ``path`` (a synthesis-input .npz or a gateway export,
    `engine.graph.inputs.read_take`) with lag ``lag_s``."""
    from engine.graph.inputs import read_take

    take = read_take(path, list(spec.sensor_names), spec.rate_hz, sensor_map, use_camera_heading=use_camera_heading,
                     times=times, start_s=start_s)
    if take.streams is not None:
        poses, _ = synthesize_streams(lambda: spec.make(lag_s), take.streams, take.stream_keys, spec.rate_hz,
                                      start_s=start_s, use_camera_heading=use_camera_heading)
        return poses
    acc = acc_in_sensor_order(path, take.obs, len(spec.sensor_names),
                              f"{spec.name} needs all its sensors {list(spec.sensor_names)}")
    return drive_take(spec.make(lag_s), acc, take.obs, int(take.frame[0]), spec.rate_hz)
