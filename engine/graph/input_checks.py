"""Validation of everything `courtside synthesize` reads: the take (.npz, both layouts), --sensor-map, --lag,
and whether the graph can explain a take that long at all.

Why a module of its own: the readers in `inputs.py` assume well-formed arrays; every check that turns a bad file
into one clear `MalformedFileError` (file + field + problem) instead of an IndexError deep in the Viterbi lives
here, next to the limits it enforces. The limits reject what cannot be a recording, not what is unusual
(`engine.recording_limits`): rates of 1 Hz..4 kHz, takes up to 6 h, finite accelerations within +-1000 g,
unit quaternions, tracks of the right shape.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from engine.array_checks import READ_ERRORS
from engine.errors import CourtsideError, MalformedFileError
from engine.export_format import ACC_G, GYRO_RPS, MESSAGES, QUAT_WXYZ, T_HOST_S, sensor_key
from engine.recording_limits import MAX_ACC_G, MAX_RATE_HZ, MAX_TAKE_S, MIN_RATE_HZ, QUAT_NORM_TOLERANCE
from engine.safe_load import parse_json

log = logging.getLogger(__name__)

MIN_FPS, MAX_FPS = MIN_RATE_HZ, MAX_RATE_HZ  # a take's rate is a recording's (engine.recording_limits)
MIN_GRAPH_SAMPLES = 2  # a path needs a start and one step
PLAUSIBLE_MEDIAN_G = 4.0  # a body's acceleration magnitude is ~1 g most of the time; ~9.8 means m/s^2


_DEVICE_FILE_HINT = "; a device recording (CSV/TSV, Xsens, x-IMU3) becomes a take with `courtside import-imu`"


def _unreadable_npz(path: Path, exc: BaseException) -> str:
    """What is wrong with a file numpy could not open as an .npz, in the user's terms (numpy's own text talks
    about allow_pickle, which means nothing to someone who gave a CSV or a folder)."""
    if path.is_dir():
        return "a folder, not a take .npz"
    if isinstance(exc, FileNotFoundError):
        return "no such file"
    if isinstance(exc, OSError):
        return f"cannot read ({exc.strerror or exc})"
    if isinstance(exc, EOFError):
        return "empty file, not an .npz archive"
    if isinstance(exc, ValueError) and "pickle" in str(exc):
        return "not an .npz archive (not a zip of numpy arrays)"
    return "not a readable .npz archive (damaged or truncated)"


def open_npz(path: Path) -> np.lib.npyio.NpzFile:
    """An .npz opened without pickle; anything else (a folder, empty, truncated, .npy, text, a pickle) is one
    MalformedFileError, with the import-imu hint once for what looks like a device recording."""
    path = Path(path)
    hint = _DEVICE_FILE_HINT if path.is_dir() or path.suffix.lower() in (".csv", ".tsv", ".txt", ".mvnx") else ""
    try:
        data = np.load(path, allow_pickle=False)
    except READ_ERRORS as exc:
        raise MalformedFileError(path, None, _unreadable_npz(path, exc) + hint) from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise MalformedFileError(path, None, "not an .npz archive (a single .npy array?)")
    return data


def array(path: Path, data, name: str, ndim: int | None = None, kind: str = "float") -> np.ndarray:
    """``data[name]`` as a float (or "str") array of ``ndim`` dimensions; a clear error when it is not."""
    try:
        value = data[name]
    except ValueError:  # object arrays need pickle, which is never allowed
        raise MalformedFileError(path, None, f"'{name}' holds Python objects (a pickle), which are never loaded; "
                                             "a take holds plain numbers and text") from None
    except READ_ERRORS as exc:  # a damaged member of the archive
        raise MalformedFileError(path, None, f"'{name}' is damaged ({exc})") from None
    if kind == "str":
        if value.dtype.kind not in "US":
            raise MalformedFileError(path, None, f"'{name}' must hold text, got dtype {value.dtype}")
    elif value.dtype.kind not in "iuf":
        raise MalformedFileError(path, None, f"'{name}' must be real numbers, got dtype {value.dtype}")
    if ndim is not None and value.ndim != ndim:
        raise MalformedFileError(path, None, f"'{name}' must have {ndim} dimension(s), got shape {value.shape}")
    return value.astype(float) if kind == "float" else value


def check_fps(path: Path, data) -> float:
    if "fps" not in data.files:
        raise MalformedFileError(path, None, "missing 'fps' (sample rate of the streams, Hz)")
    fps = array(path, data, "fps")
    if fps.shape != ():
        raise MalformedFileError(path, None, f"'fps' must be one number, got shape {fps.shape}")
    fps = float(fps)
    if not MIN_FPS <= fps <= MAX_FPS:  # also refuses NaN
        raise MalformedFileError(path, None, f"'fps' = {fps!r} Hz is outside {MIN_FPS:g}..{MAX_FPS:g} Hz")
    return fps


def check_take_file(path: Path, data) -> None:
    """The one check of a take in the synthesis-input layout, shared by `courtside synthesize` and `courtside
    calibrate` (issue 30: calibrate accepted takes synthesize refused, and failed on them with tracebacks):
    acc_g (T, S, 3) with T >= 2 and S >= 1, finite and within +-`MAX_ACC_G`; fps one number in the recording
    limits; at most `MAX_TAKE_S` long; optional sensor_names and source_labels (S,) text naming each column once;
    position_m (T, 2), heading_rad (T,); optional quat_wxyz / gyro_rps (`check_channels`)."""
    acc = array(path, data, "acc_g", 3)
    if acc.shape[2] != 3 or acc.shape[0] < 2 or acc.shape[1] < 1:
        raise MalformedFileError(path, None, f"acc_g must have shape (T, S, 3) with at least 2 samples and one "
                                             f"sensor, got {acc.shape}")
    fps = check_fps(path, data)
    if len(acc) / fps > MAX_TAKE_S:
        raise MalformedFileError(path, None, f"{len(acc)} samples at {fps:g} Hz last {len(acc) / fps / 3600:.3g} h, "
                                             f"more than the {MAX_TAKE_S / 3600:g} h a take may last")
    _check_acceleration(path, "acc_g", acc, fps)
    for key in ("sensor_names", "source_labels"):
        if key in data.files:
            names = [str(n) for n in array(path, data, key, 1, kind="str")]
            if len(names) != acc.shape[1]:
                raise MalformedFileError(path, None, f"{key} has {len(names)} entries for acc_g's "
                                                     f"{acc.shape[1]} sensor columns")
            if len(set(names)) != len(names):
                raise MalformedFileError(path, None, f"{key} {names} name a sensor twice")
    n = len(acc)
    if "position_m" in data.files:
        pos = array(path, data, "position_m", 2)
        if pos.shape != (n, 2):
            raise MalformedFileError(path, None, f"position_m must have shape ({n}, 2) like acc_g's {n} samples, "
                                                 f"got {pos.shape}")
    if "heading_rad" in data.files:
        head = array(path, data, "heading_rad", 1)
        if head.shape != (n,):
            raise MalformedFileError(path, None, f"heading_rad must have shape ({n},), got {head.shape}")
    check_channels(path, data, "", acc.shape[:2])


def check_channels(path: Path, data, prefix: str, leading: tuple[int, ...]) -> None:
    """Optional ``<prefix>quat_wxyz`` (*leading, 4) unit quaternions and ``<prefix>gyro_rps`` (*leading, 3) rad/s:
    shaped like the accelerations, each row all finite or all NaN (a sensor with no value there)."""
    for name, width in ((QUAT_WXYZ, 4), (GYRO_RPS, 3)):
        key = prefix + name
        if key not in data.files:
            continue
        values = array(path, data, key, len(leading) + 1)
        if values.shape != (*leading, width):
            raise MalformedFileError(path, None, f"{key} must have shape {(*leading, width)} like the "
                                                 f"accelerations, got {values.shape}")
        finite = np.isfinite(values)
        partial = finite.any(axis=-1) & ~finite.all(axis=-1)
        if partial.any() or np.isinf(values).any():
            where = tuple(int(i) for i in np.argwhere(partial | np.isinf(values).any(axis=-1))[0])
            raise MalformedFileError(path, None, f"{key} row {where} is neither finite nor all NaN")
        if name == QUAT_WXYZ:
            norm = np.linalg.norm(np.where(finite, values, 0.0), axis=-1)
            bad = finite.all(axis=-1) & (np.abs(norm - 1.0) > QUAT_NORM_TOLERANCE)
            if bad.any():
                where = tuple(int(i) for i in np.argwhere(bad)[0])
                raise MalformedFileError(path, None, f"{key} holds {int(bad.sum())} quaternion(s) that are not unit "
                                                     f"length (first at {where}: norm {norm[where]:.4g})")


def check_gateway_export(path: Path, data, keys: list[str]) -> None:
    """The export layout: per recorded sensor ``<key>/acc_g`` (N, 3) and ``<key>/t_host_s`` (N,) increasing."""
    for key in keys:
        acc_key, t_key = sensor_key(key, ACC_G), sensor_key(key, T_HOST_S)
        if t_key not in data.files:
            raise MalformedFileError(path, None, f"'{acc_key}' has no '{t_key}' beside it")
        acc = array(path, data, acc_key, 2)
        t = array(path, data, t_key, 1)
        if acc.shape[1] != 3 or len(acc) != len(t):
            raise MalformedFileError(path, None, f"'{key}': acc_g {acc.shape} and t_host_s {t.shape} must be "
                                                 "(N, 3) and (N,)")
        # a real recording may step back now and then (the online clock map re-fits; engine.stream drops samples
        # that are not after every earlier one, live and offline alike), but overall its times must increase
        if len(t) < 2 or not np.all(np.isfinite(t)) or not t[-1] > t[0] or np.mean(np.diff(t) > 0) < 0.5:
            raise MalformedFileError(path, None, f"'{t_key}' must hold at least 2 finite, increasing times")
        _check_acceleration(path, acc_key, acc[:, None], 1.0 / float(np.median(np.diff(t))))
        check_channels(path, data, sensor_key(key, ""), (len(acc),))
    if MESSAGES in data.files:
        messages = parse_json(str(array(path, data, MESSAGES, 0, kind="str")), f"{path}: '{MESSAGES}'")
        if not isinstance(messages, list) or not all(isinstance(m, dict) for m in messages):
            raise MalformedFileError(path, None, "'messages' must be a JSON list of objects")
        for i, m in enumerate(messages):
            if m.get("kind") == "camera" and m.get("position_m") is not None:
                ok = isinstance(m.get("t_host_s"), (int, float)) and isinstance(m["position_m"], list) \
                     and len(m["position_m"]) >= 2 and all(isinstance(v, (int, float)) for v in m["position_m"][:2])
                heading = m.get("heading_rad")
                if not ok or (heading is not None and not isinstance(heading, (int, float))):
                    raise MalformedFileError(path, None, f"camera message {i} needs a numeric t_host_s, position_m "
                                                         f"[x, y] and heading_rad, got {json.dumps(m)[:120]}")


def _check_acceleration(path: Path, name: str, acc: np.ndarray, fps: float) -> None:
    """acc (T, S, 3) must be finite (a NaN would poison every path cost of the search) and within +-`MAX_ACC_G`
    (no worn sensor reads more: a wrong column or unit)."""
    bad = ~np.isfinite(acc).all(axis=2)
    if bad.any():
        t, s = np.argwhere(bad)[0]
        raise MalformedFileError(path, None, f"{name} holds {int(bad.sum())} non-finite sample(s) (first at sample "
                                             f"{t} = {t / fps:.3f} s, sensor column {s})")
    beyond = (np.abs(acc) > MAX_ACC_G).any(axis=2)
    if beyond.any():
        t, s = np.argwhere(beyond)[0]
        raise MalformedFileError(path, None, f"{name} holds values beyond +-{MAX_ACC_G:g} g (first at sample {t}, "
                                             f"sensor column {s}: {acc[t, s].tolist()})")


def check_observations(path: Path, acc_g: np.ndarray | None, fps_graph: float) -> None:
    """After resampling (the raw values were checked finite): enough samples for a path, and a units plausibility
    warning."""
    if acc_g is None:
        return
    if len(acc_g) < MIN_GRAPH_SAMPLES:
        raise MalformedFileError(path, None, f"the take is too short: {len(acc_g)} sample(s) at the graph rate "
                                             f"{fps_graph:g} Hz (at least {MIN_GRAPH_SAMPLES} needed)")
    median_g = float(np.median(np.linalg.norm(acc_g, axis=2)))
    if median_g > PLAUSIBLE_MEDIAN_G:
        log.warning("warning: %s: acc_g has a median magnitude of %.1f g; a worn sensor reads about 1 g most of "
                    "the time, so these look like m/s^2 (divide by 9.81)", path, median_g)


def parse_sensor_map(items: list[str] | None, graph_sensors: list[str],
                     known_as: str = "a sensor of the graph") -> dict[str, str] | None:
    """``STATION/SENSOR=NAME`` items -> {recorded key: graph sensor}; errors name --sensor-map and the item
    (``known_as`` says what the names must be)."""
    if not items:
        return None
    out: dict[str, str] = {}
    for item in items:
        key, sep, name = item.partition("=")
        if not sep or not key or not name:
            raise CourtsideError(f"--sensor-map {item!r}: expected STATION/SENSOR=NAME")
        if name not in graph_sensors:
            raise CourtsideError(f"--sensor-map {item!r}: {name!r} is not {known_as} ({graph_sensors})")
        out[key] = name
    return out


def check_sensor_map(path: Path, sensor_map: dict[str, str] | None, keys: list[str]) -> None:
    unknown = sorted(set(sensor_map or {}) - set(keys))
    if unknown:
        raise MalformedFileError(path, None, f"--sensor-map names {unknown}, which the recording does not hold "
                                             f"(it holds {keys})")


def check_non_negative(option: str, values: list[float], positive: bool = False) -> None:
    """Command-line numbers that must be finite and >= 0 (> 0 with ``positive``): weights, thresholds."""
    for v in values:
        if not np.isfinite(v) or v < 0 or (positive and v == 0):
            raise CourtsideError(f"{option} {v!r}: must be a finite number {'> 0' if positive else '>= 0'}")


def check_lag(lag_s: float | None, fps: float) -> None:
    if lag_s is not None and not (np.isfinite(lag_s) and lag_s >= 0 and lag_s * fps <= 1e6):
        raise CourtsideError(f"--lag {lag_s!r}: must be a non-negative number of seconds")


def longest_path_samples(src: np.ndarray, dst: np.ndarray, n_nodes: int) -> float:
    """Samples on the longest path of the graph: inf if it has a cycle (a walk can go on for ever)."""
    if n_nodes == 0:
        return 0.0
    if np.any(src == dst):
        return float("inf")
    adjacency = coo_matrix((np.ones(len(src)), (src, dst)), shape=(n_nodes, n_nodes)).tocsr()
    n_components, _ = connected_components(adjacency, directed=True, connection="strong")
    if n_components < n_nodes:
        return float("inf")
    # acyclic: longest path by relaxing edges in topological order (Kahn), vectorised per frontier
    indegree = np.bincount(dst, minlength=n_nodes)
    length = np.ones(n_nodes)
    frontier = np.flatnonzero(indegree == 0)
    indptr, indices = adjacency.indptr, adjacency.indices
    while frontier.size:
        starts, stops = indptr[frontier], indptr[frontier + 1]
        counts = stops - starts
        edges = np.concatenate([indices[a:b] for a, b in zip(starts, stops)]) if counts.sum() else np.empty(0, int)
        from_len = np.repeat(length[frontier], counts)
        np.maximum.at(length, edges, from_len + 1)
        np.subtract.at(indegree, edges, 1)
        frontier = np.unique(edges[indegree[edges] == 0])
    return float(length.max())


def check_path_length(graph_path: Path, src: np.ndarray, dst: np.ndarray, n_nodes: int, n_samples: int,
                      fps: float) -> None:
    """A take longer than every path through the graph has no explanation (the search would find none)."""
    longest = longest_path_samples(np.asarray(src), np.asarray(dst), n_nodes)
    if longest < n_samples:
        raise MalformedFileError(graph_path, None, f"the graph's longest path is {int(longest)} samples "
                                                   f"({longest / fps:.2f} s) but the take has {n_samples} "
                                                   f"({n_samples / fps:.2f} s): build it from more clips or with "
                                                   "transitions")


_INDEX_ARRAYS = ("edge_src", "edge_dst", "edge_meta", "edge_kind", "node_clip", "node_clip2", "node_kind",
                 "node_label", "node_arrival")
_FINITE_ARRAYS = ("node_positions_m", "node_rotations", "node_root_m", "node_ground_m", "node_heading_rad",
                  "meta_acc_g", "meta_dpos_m", "meta_dheading_rad", "node_frame")
_TRAILING_SHAPES = {"node_positions_m": (3,), "node_rotations": (4,), "node_root_m": (3,), "node_ground_m": (2,),
                    "meta_acc_g": (3,), "meta_dpos_m": (2,)}


def graph_arrays_problem(arrays: dict[str, np.ndarray], n_joints: int | None, parents: np.ndarray | None) -> str | None:
    """What makes a motion graph's arrays unusable beyond `MotionGraph.inconsistency` (dtypes, trailing shapes,
    non-finite values, skeleton links), or None."""
    for name in _INDEX_ARRAYS:
        if name in arrays and arrays[name].dtype.kind not in "iu":
            return f"'{name}' must hold integers, got dtype {arrays[name].dtype}"
    for name, trailing in _TRAILING_SHAPES.items():
        value = arrays.get(name)
        if value is not None and (value.ndim < 2 or value.shape[-1:] != trailing):
            return f"'{name}' has shape {value.shape}, expected (..., {trailing[0]})"
    for name in ("node_positions_m", "node_rotations"):
        value = arrays.get(name)
        if value is not None and n_joints is not None and (value.ndim != 3 or value.shape[1] != n_joints):
            return f"'{name}' has shape {value.shape}, expected (nodes, {n_joints} joints, ...)"
    for name in _FINITE_ARRAYS:
        value = arrays.get(name)
        if value is not None and (value.dtype.kind not in "iuf" or not np.all(np.isfinite(value))):
            return f"'{name}' holds non-finite or non-numeric values"
    if parents is not None:
        p = np.asarray(parents)
        if p.ndim != 1 or p.dtype.kind not in "iu" or len(p) == 0 or p[0] != -1 or \
                np.any((p[1:] < 0) | (p[1:] >= np.arange(1, len(p)))):
            return "skeleton_parents must list each joint's parent before it (root -1)"
    return None


MIN_CLIP_FRAMES = 3  # the graph differentiates positions twice


def check_database(paths: list[Path], motions: list, fps: float) -> None:
    """Clips that cannot go into a graph, named by file: too short at the graph rate, or a skeleton whose joint
    names match no convention (no sensor can be placed on it)."""
    from engine.mocap.roles import UnknownSkeletonError, joint_roles

    for path, motion in zip(paths, motions):
        if motion.n_frames < MIN_CLIP_FRAMES:
            raise MalformedFileError(path, None, f"too short for a graph: {motion.n_frames} frame(s) at {fps:g} Hz "
                                                 f"(at least {MIN_CLIP_FRAMES})")
    if motions:
        try:
            joint_roles(motions[0].skeleton)
        except UnknownSkeletonError as exc:
            raise MalformedFileError(paths[0], None, str(exc)) from None

