"""Reading a recorded take for synthesis, brought to the graph's frame clock by the one sample -> frame path
(`engine.stream`: box-filtered resampling, dropouts marked and never interpolated, camera fix per frame time).

Two file layouts are accepted (both .npz):

* the synthesis input format (documented in docs/engine-graph.md):
  `acc_g` (T, S, 3) g; `fps` scalar Hz (all streams share it); optional `sensor_names` (S,) graph sensor names of
  the acc columns (default: the graph's first S sensors); optional `position_m` (T, 2) ground (x, z) m and
  `heading_rad` (T,) rad, NaN where missing; optional `quat_wxyz` (T, S, 4) sensor -> the device's earth frame
  (Z up, yaw arbitrary per sensor) and `gyro_rps` (T, S, 3) rad/s, NaN rows where a sensor has no value.
  Sample i is at time i / fps.
* the gateway's export (`courtside gateway export --npz`): per sensor `<station>/<sensor>/acc_g` (N, 3) and
  `<station>/<sensor>/t_host_s` (N,) (or `t_realigned_s`, the offline clock re-fit), and from sensors that stream
  them `<station>/<sensor>/quat_wxyz` (N, 4) and `/gyro_rps` (N, 3); they map to graph sensors
  in sorted (station, sensor) order unless a mapping is given. Recorded camera messages (in the `messages` JSON:
  `t_host_s`, `position_m` court [x, y] or null, `heading_rad`) are the camera track; the recording's `meta`
  (`started_t_host_s`) fixes the take's first frame (`engine.stream.take_start_s`), exactly as the console
  does live, so the same take gives the same frames live and offline.

The tracker's heading is used only when asked (``use_camera_heading``), as live; a synthesis-input file's own
`heading_rad` is always used, and if it has a position track without heading the seed-000 heuristic fills it in:
the direction of motion when the speed exceeds 2 m/s, otherwise facing the net (court y = world z = 0).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.errors import MalformedFileError
from engine.export_format import (ACC_G, MESSAGES, META, OPTIONAL_CHANNELS, TIME_COLUMNS, recorded_sensors,
                                  sensor_key)
from engine.mocap import SEED_HEADING_SPEED_MPS, seed_heading_rule
from engine.safe_load import parse_json
from engine.stream import CameraTrack, FrameBatch, FrameResampler, RecordedStreams, resample_uniform, take_start_s

from .input_checks import check_gateway_export, check_observations, check_sensor_map, check_take_file, open_npz
from .viterbi import Observations

HEURISTIC_SPEED_MPS = SEED_HEADING_SPEED_MPS


@dataclass
class TakeFrames:
    """A take on the frame clock: the observations, each frame's index and gateway time, and (gateway exports)
    the raw recorded streams with the live sensor feeding each observation column."""

    obs: Observations
    frame: np.ndarray   # (T,) int64 frame index (t_s = frame / fps)
    t_s: np.ndarray     # (T,) s
    streams: RecordedStreams | None = None
    stream_keys: list[str] | None = None


def heading_heuristic(position_m: np.ndarray, fps: float, speed_threshold_mps: float = HEURISTIC_SPEED_MPS,
                      smooth_s: float = 0.2) -> np.ndarray:
    """Heading (rad) from a ground track (T, 2) by `engine.mocap.seed_heading_rule`, on velocities from the
    track smoothed over `smooth_s` seconds (camera positions are noisy; a raw gradient would flicker)."""
    from scipy.ndimage import uniform_filter1d

    pos = uniform_filter1d(np.asarray(position_m, float), max(1, int(round(smooth_s * fps))), axis=0)
    return seed_heading_rule(pos, np.gradient(pos, axis=0) * fps, speed_threshold_mps)


def _track_at(values_t_s: np.ndarray, positions: np.ndarray | None, headings: np.ndarray | None,
              frames_t_s: np.ndarray, max_gap_s: float) -> tuple[np.ndarray, np.ndarray]:
    """A sampled position/heading track at frame times, by the camera-track rule (bracketing samples)."""
    track = CameraTrack(max_gap_s)
    for k, t in enumerate(values_t_s):
        pos = None if positions is None or np.isnan(positions[k]).any() else positions[k]
        head = None if headings is None or np.isnan(headings[k]) else float(headings[k])
        track.add(float(t), pos, head)
    return track.at(frames_t_s)


def _from_synthesis_file(path: Path, data, graph_sensors: list[str], fps_graph: float) -> TakeFrames:
    check_take_file(path, data)  # shapes, fps, finite values: past here they are sound
    acc = np.asarray(data["acc_g"], float)
    fps = float(data["fps"])
    names = [str(n) for n in data["sensor_names"]] if "sensor_names" in data.files else graph_sensors[:acc.shape[1]]
    used = None
    if len(names) == acc.shape[1] and any(n in graph_sensors for n in names):  # drop sensors the graph lacks
        used = [k for k, n in enumerate(names) if n in graph_sensors]
        acc, names = acc[:, used], [names[k] for k in used]
    unknown = [n for n in names if n not in graph_sensors]
    if unknown or len(names) != acc.shape[1]:
        raise MalformedFileError(path, None, f"sensor names {names} do not match the acc_g columns / graph "
                                             f"sensors {graph_sensors}")
    channels = {name: np.asarray(data[name], float)[:, used] if used is not None else np.asarray(data[name], float)
                for name in OPTIONAL_CHANNELS if name in data.files}
    frames = resample_uniform(acc, fps, fps_graph, **channels)
    if not len(frames):
        raise MalformedFileError(path, None, f"{len(acc)} samples at {fps:g} Hz are less than one frame")
    t_in = np.arange(len(acc)) / fps
    gap = max(1.5 / fps, 1.0 / fps_graph)
    pos = head = None
    if "position_m" in data.files:
        pos, _ = _track_at(t_in, np.asarray(data["position_m"], float), None, frames.t_s, gap)
    if "heading_rad" in data.files:
        _, head = _track_at(t_in, np.zeros((len(acc), 2)), np.asarray(data["heading_rad"], float), frames.t_s, gap)
    elif pos is not None:
        head = heading_heuristic(pos, fps_graph)
    obs = Observations(frames.acc_g, pos, head, tuple(graph_sensors.index(n) for n in names), frames.quat_wxyz,
                       frames.gyro_rps)
    return TakeFrames(obs, frames.index, frames.t_s)


def recorded_streams(path: Path, data, graph_sensors: list[str], sensor_map: dict[str, str] | None,
                     times: str = "t_host_s") -> tuple[RecordedStreams, list[str], tuple[int, ...]]:
    """A gateway export's raw streams: (streams, live stream key per observation column, graph sensor index per
    column). Columns are in graph-sensor order, as the console feeds them live."""
    if times not in TIME_COLUMNS:
        raise ValueError(f"times must be one of {TIME_COLUMNS}, not {times!r}")
    keys = recorded_sensors(data.files)
    if not keys:
        raise MalformedFileError(path, None, "no 'acc_g' array and no '<station>/<sensor>/acc_g' arrays")
    check_gateway_export(path, data, keys)
    check_sensor_map(path, sensor_map, keys)
    mapping = sensor_map or dict(zip(keys, graph_sensors))
    missing = [k for k in mapping if k not in keys]
    if missing or any(v not in graph_sensors for v in mapping.values()) or len(set(mapping.values())) < len(mapping):
        raise MalformedFileError(path, None, f"cannot map recorded sensors {keys} onto graph sensors "
                                             f"{graph_sensors} with {mapping}")
    used = sorted(mapping, key=lambda k: graph_sensors.index(mapping[k]))
    samples = {}
    for k in used:
        if sensor_key(k, times) not in data.files:
            raise MalformedFileError(path, None, f"sensor {k} has no '{times}' array")
        samples[k] = (np.asarray(data[sensor_key(k, times)], float), np.asarray(data[sensor_key(k, ACC_G)], float))
        if any(sensor_key(k, c) in data.files for c in OPTIONAL_CHANNELS):  # (t, acc, quat, gyro), None = absent
            samples[k] += tuple(np.asarray(data[sensor_key(k, c)], float) if sensor_key(k, c) in data.files else None
                                for c in OPTIONAL_CHANNELS)
    meta = _json(path, data, META, {})
    if not isinstance(meta, dict):
        raise MalformedFileError(path, None, "'meta' must be a JSON object (the recording's header)")
    cams = [m for m in _json(path, data, MESSAGES, []) if m.get("kind") == "camera" and m.get("t_host_s") is not None]
    cams.sort(key=lambda m: float(m["t_host_s"]))
    camera = [(float(m["t_host_s"]), m.get("position_m"), m.get("heading_rad")) for m in cams]
    streams = RecordedStreams(samples, camera, meta.get("started_t_host_s"))
    return streams, used, tuple(graph_sensors.index(mapping[k]) for k in used)


def _json(path: Path, data, name: str, default):
    if name not in data.files:
        return default
    return parse_json(str(data[name]), f"{path}: '{name}'")


def _from_gateway_export(path: Path, data, graph_sensors: list[str], fps_graph: float,
                         sensor_map: dict[str, str] | None, use_camera_heading: bool, times: str,
                         start_s: float | None) -> TakeFrames:
    streams, keys, indices = recorded_streams(path, data, graph_sensors, sensor_map, times)
    if start_s is None and streams.started_t_host_s is not None:
        start_s = take_start_s(streams.started_t_host_s)
    resampler = FrameResampler(keys, fps_graph)
    for k in keys:
        resampler.add(k, *streams.samples[k])
    resampler.start_at(start_s)
    frames: FrameBatch = resampler.frames()
    if not frames.valid.any():
        raise MalformedFileError(path, None, "the sensors' recordings do not overlap in time (no frame has every "
                                             "sensor's samples)")
    track = CameraTrack()
    for t, pos, head in streams.camera:
        track.add(t, pos, head)
    pos, head = track.at(frames.t_s)
    obs = Observations(frames.acc_g, pos if streams.camera else None,
                       head if streams.camera and use_camera_heading else None, indices, frames.quat_wxyz,
                       frames.gyro_rps)
    return TakeFrames(obs, frames.index, frames.t_s, streams, keys)


def read_take(path: str | Path, graph_sensors: list[str], fps_graph: float, sensor_map: dict[str, str] | None = None,
              *, use_camera_heading: bool = False, times: str = "t_host_s", start_s: float | None = None) -> TakeFrames:
    """A synthesis-input .npz or a gateway export on the frame clock (see the module doc)."""
    path = Path(path)
    with open_npz(path) as data:  # its error has the import-imu hint for a device recording
        if "acc_g" in data.files:
            take = _from_synthesis_file(path, data, graph_sensors, fps_graph)
        else:
            take = _from_gateway_export(path, data, graph_sensors, fps_graph, sensor_map, use_camera_heading, times,
                                        start_s)
    check_observations(path, take.obs.acc_g, fps_graph)
    return take


def load_take(path: str | Path, graph_sensors: list[str], fps_graph: float,
              sensor_map: dict[str, str] | None = None, **options) -> Observations:
    """Observations at the graph rate from a synthesis-input .npz or a gateway export (`read_take`)."""
    return read_take(path, graph_sensors, fps_graph, sensor_map, **options).obs
