"""Reading a recorded take for synthesis and bringing it to the graph rate.

Two file layouts are accepted (both .npz):

* the synthesis input format (documented in docs/engine-graph.md):
  `acc_g` (T, S, 3) g; `fps` scalar Hz (all streams share it); optional `sensor_names` (S,) graph sensor names of
  the acc columns (default: the graph's first S sensors); optional `position_m` (T, 2) ground (x, z) m and
  `heading_rad` (T,) rad, NaN where missing.
* the gateway's export (`courtside gateway` recording -> `export_npz`): per sensor `<station>/<sensor>/acc_g`
  (N, 3) and `<station>/<sensor>/t_host_s` (N,). Sensors are put on a common time grid; they map to graph
  sensors in sorted (station, sensor) order unless a mapping is given. Recorded camera messages (in the
  `messages` JSON: `t_host_s`, `position_m` court [x, y], `heading_rad`) become the position/heading track.

If a position track is given without heading, the seed-000 heuristic fills it in: the direction of motion when
the speed exceeds 2 m/s, otherwise facing the net (court y = world z = 0).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from engine.errors import MalformedFileError
from engine.mocap import SEED_HEADING_SPEED_MPS, seed_heading_rule

from .input_checks import check_gateway_export, check_observations, check_sensor_map, check_synthesis_file, open_npz
from .online import resample_stream
from .viterbi import Observations

HEURISTIC_SPEED_MPS = SEED_HEADING_SPEED_MPS


def heading_heuristic(position_m: np.ndarray, fps: float, speed_threshold_mps: float = HEURISTIC_SPEED_MPS,
                      smooth_s: float = 0.2) -> np.ndarray:
    """Heading (rad) from a ground track (T, 2) by `engine.mocap.seed_heading_rule`, on velocities from the
    track smoothed over `smooth_s` seconds (camera positions are noisy; a raw gradient would flicker)."""
    from scipy.ndimage import uniform_filter1d

    pos = uniform_filter1d(np.asarray(position_m, float), max(1, int(round(smooth_s * fps))), axis=0)
    return seed_heading_rule(pos, np.gradient(pos, axis=0) * fps, speed_threshold_mps)


def _interp_track(values: np.ndarray, fps_in: float, n_out: int, fps_out: float, angle: bool = False) -> np.ndarray:
    """Linear interpolation of a slowly varying track (position/heading) onto the graph-rate grid."""
    t_in = np.arange(len(values)) / fps_in
    t_out = np.arange(n_out) / fps_out
    v = np.unwrap(values) if angle else values
    if v.ndim == 1:
        return np.interp(t_out, t_in, v)
    return np.stack([np.interp(t_out, t_in, v[:, k]) for k in range(v.shape[1])], axis=1)


def _from_synthesis_file(path: Path, data, graph_sensors: list[str], fps_graph: float) -> Observations:
    check_synthesis_file(path, data, graph_sensors)  # shapes, fps, finite values: past here they are sound
    acc = np.asarray(data["acc_g"], float)
    fps = float(data["fps"])
    names = [str(n) for n in data["sensor_names"]] if "sensor_names" in data.files else graph_sensors[:acc.shape[1]]
    if len(names) == acc.shape[1] and any(n in graph_sensors for n in names):  # drop sensors the graph lacks
        used = [k for k, n in enumerate(names) if n in graph_sensors]
        acc, names = acc[:, used], [names[k] for k in used]
    unknown = [n for n in names if n not in graph_sensors]
    if unknown or len(names) != acc.shape[1]:
        raise MalformedFileError(path, None, f"sensor names {names} do not match the acc_g columns / graph "
                                             f"sensors {graph_sensors}")
    acc_r = resample_stream(acc, fps, fps_graph)
    n = len(acc_r)
    pos = head = None
    if "position_m" in data.files:
        pos = _interp_track(np.asarray(data["position_m"], float), fps, n, fps_graph)
    if "heading_rad" in data.files:
        head = _interp_track(np.asarray(data["heading_rad"], float), fps, n, fps_graph, angle=True)
    elif pos is not None:
        head = heading_heuristic(pos, fps_graph)
    return Observations(acc_r, pos, head, tuple(graph_sensors.index(n) for n in names))


def _from_gateway_export(path: Path, data, graph_sensors: list[str], fps_graph: float,
                         sensor_map: dict[str, str] | None) -> Observations:
    keys = sorted({k.rsplit("/", 1)[0] for k in data.files if k.endswith("/acc_g")})
    if not keys:
        raise MalformedFileError(path, None, "no 'acc_g' array and no '<station>/<sensor>/acc_g' arrays")
    check_gateway_export(path, data, keys)
    check_sensor_map(path, sensor_map, keys)
    mapping = sensor_map or dict(zip(keys, graph_sensors))
    missing = [k for k in keys if k not in mapping]
    if missing or any(v not in graph_sensors for v in mapping.values()):
        raise MalformedFileError(path, None, f"cannot map recorded sensors {keys} onto graph sensors {graph_sensors}")
    streams = [(np.asarray(data[f"{k}/t_host_s"], float), np.asarray(data[f"{k}/acc_g"], float)) for k in keys]
    t0 = max(t[0] for t, _ in streams)
    t1 = min(t[-1] for t, _ in streams)
    rate = min(1.0 / np.median(np.diff(t)) for t, _ in streams)
    if not t1 > t0:
        raise MalformedFileError(path, None, "the sensors' recordings do not overlap in time")
    grid = np.arange(t0, t1, 1.0 / rate)
    acc = np.stack([np.stack([np.interp(grid, t, a[:, k]) for k in range(3)], axis=1) for t, a in streams], axis=1)
    acc_r = resample_stream(acc, rate, fps_graph)
    t_out = t0 + np.arange(len(acc_r)) / fps_graph
    pos, head = _camera_track(path, data, t_out)
    if pos is not None and head is not None and np.all(np.isnan(head)):
        head = heading_heuristic(np.nan_to_num(pos), fps_graph)
    return Observations(acc_r, pos, head, tuple(graph_sensors.index(mapping[k]) for k in keys))


def _camera_track(path: Path, data, t_out: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Court position (court (x, y) = world (x, z), m) and heading from the export's recorded camera messages,
    interpolated to the sample times; NaN outside the tracked span. (None, None) if there are none."""
    if "messages" not in data.files:
        return None, None
    try:
        messages = json.loads(str(data["messages"]))
    except json.JSONDecodeError as exc:
        raise MalformedFileError(path, None, f"'messages' is not JSON ({exc})") from exc
    cams = [m for m in messages if m.get("kind") == "camera" and m.get("position_m") is not None]
    if len(cams) < 2:
        return None, None
    t = np.array([float(m["t_host_s"]) for m in cams])
    order = np.argsort(t)
    t = t[order]
    xy = np.array([m["position_m"][:2] for m in cams], float)[order]
    heading = np.array([np.nan if m.get("heading_rad") is None else float(m["heading_rad"]) for m in cams])[order]
    inside = (t_out >= t[0]) & (t_out <= t[-1])
    pos = np.full((len(t_out), 2), np.nan)
    pos[inside] = np.stack([np.interp(t_out[inside], t, xy[:, k]) for k in range(2)], axis=1)
    head = np.full(len(t_out), np.nan)
    known = ~np.isnan(heading)
    if known.sum() >= 2:
        head[inside] = np.interp(t_out[inside], t[known], np.unwrap(heading[known]))
    return pos, head


def load_take(path: str | Path, graph_sensors: list[str], fps_graph: float,
              sensor_map: dict[str, str] | None = None) -> Observations:
    """Observations at the graph rate from a synthesis-input .npz or a gateway export."""
    path = Path(path)
    with open_npz(path) as data:
        if "acc_g" in data.files:
            obs = _from_synthesis_file(path, data, graph_sensors, fps_graph)
        else:
            obs = _from_gateway_export(path, data, graph_sensors, fps_graph, sensor_map)
    check_observations(path, obs.acc_g, fps_graph)
    return obs
