"""The motion graph in the engine registry (`engine.stream.registry`): its spec, database builder and online
engine.

The online engine is `engine.graph.online.FixedLagSynthesizer` itself (it speaks the `OnlineEngine` protocol).
Its default database is a graph over the shipped clips, cached as .npz keyed by the clip files, sensor names,
graph config and calibrated rotations, so a second start only loads it. With a sensor-calibration record (written
by the gateway's calibration workflow) the graph's virtual sensors use the measured sensor-to-segment rotations
(`engine.mocap.placements_from_calibration`); each calibration gets its own cached graph. When the record also
calibrated every worn sensor's orientation (its earth-frame yaw and strapping, issue 18), the decoder poses the
worn segments with their yaw relative to the pelvis (`orientation_pose.SegmentPosing`), else with their tilt
only; the status bar says which."""
from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from engine.mocap import (SEED000_SENSORS, Motion, SensorCalibrationData, Skeleton, default_cache_dir, load_clip,
                          placements_from_calibration, standard_placements)
from engine.mocap.orientation_calibration import OrientationCalibration
from engine.stream.databases import GRAPH_FPS, shipped_clip_paths
from engine.stream.engines import ACC, ORIENTATION, EngineMismatchError, EngineSpec

from .config import GraphConfig
from .graph import MotionGraph


def motion_graph_spec(graph: MotionGraph, database: str | Path, skeleton: Any = None, warp: Any = None,
                      fusion: Any = None, orientation_calibration: OrientationCalibration | None = None,
                      reading_corrections: np.ndarray | None = None) -> EngineSpec:
    """Fixed-lag Viterbi over a `MotionGraph` (from `courtside build-graph` or the console's cache), with
    `courtside synthesize`'s defaults: root warping towards the camera (``warp``, default
    `engine.graph.warp.RootWarp()`) and the weights that go with it, the output root fused from the camera track
    (``fusion``, default `engine.graph.root_fusion.RootFusion()`). The confidence reference (the cost per sample
    of the graph's own clips) is measured once here, not at every engine restart. ``orientation_calibration``
    (the graph's sensors in order, `SensorCalibrationData.orientation_calibration`): segments posed with their yaw
    relative to the pelvis, else by tilt only. ``reading_corrections`` (S, 3, 3): each pushed frame's
    accelerations turned into the graph's nominal sensor frames first (calibrated_input.CorrectedReadings)."""
    from .calibrated_input import CorrectedReadings
    from .confidence import reference_cost_per_sample
    from .online import FixedLagSynthesizer
    from .orientation_term import places_sensors
    from .root_fusion import RootFusion
    from .viterbi import default_weights
    from .warp import RootWarp

    skeleton = graph.skeleton if skeleton is None else skeleton
    if skeleton is None:
        raise EngineMismatchError(f"{database}: the graph holds no skeleton (rebuild it with build-graph)")
    names = tuple(graph.config.sensor_names)
    if len(names) != graph.n_sensors:
        raise EngineMismatchError(f"{database}: graph has {graph.n_sensors} sensor columns but names {list(names)}")
    warp = RootWarp() if warp is None else warp
    fusion = RootFusion() if fusion is None else fusion
    weights = default_weights(warp)
    reference = reference_cost_per_sample(graph, weights, warp)
    # orientations feed the search's term (camera-following preset) and pose the worn segments, when the graph's
    # poses place its sensors
    listens = places_sensors(graph) and (weights.orientation > 0 or weights.segment_pose > 0)
    inputs = (ACC, ORIENTATION) if listens else (ACC,)
    note = "" if not (listens and weights.segment_pose > 0) else \
        "calibrated yaw" if orientation_calibration is not None else "tilt only"

    def make(lag_s: float) -> Any:
        engine = FixedLagSynthesizer(graph, lag_s, weights, warp=warp, confidence_reference=reference, fusion=fusion,
                                     orientation_calibration=orientation_calibration)
        return engine if reading_corrections is None else CorrectedReadings(engine, reading_corrections)

    return EngineSpec("motion-graph", str(database), names, float(graph.config.fps), np.asarray(skeleton.parents),
                      make,
                      graph=graph,
                      skeleton=skeleton,
                      inputs=inputs,
                      inputs_note=note)


CACHE_CONTENTS = "2: graphs store their sensor rotations"  # a change of what a cached graph holds starts a new cache


def graph_cache_path(clip_paths: Sequence[Path], sensor_names: Sequence[str], config: GraphConfig,
                     cache_dir: Path | None = None, calibration: SensorCalibrationData | None = None) -> Path:
    """Cache file name from the clip files' identity (path, size, mtime), sensors, config and the calibrated
    rotations (if any)."""
    parts = [json.dumps(list(sensor_names)), config.to_json(), CACHE_CONTENTS]
    if calibration is not None:
        parts.append(calibration.fingerprint())
    parts += [f"{p.resolve()}|{p.stat().st_size}|{p.stat().st_mtime_ns}" for p in sorted(clip_paths)]
    digest = hashlib.sha1("\n".join(parts).encode()).hexdigest()[:16]
    return (cache_dir or default_cache_dir().parent / "graphs") / f"graph-{digest}.npz"


def load_or_build_graph(exclude: Sequence[str] = (), sensor_names: Sequence[str] = SEED000_SENSORS,
                        cache_dir: Path | None = None, calibration: SensorCalibrationData | None = None
                        ) -> tuple[MotionGraph, Skeleton, Path]:
    """Graph over the shipped CMU subject-16 clips (one skeleton topology), minus ``exclude`` clip names; with
    ``calibration`` (`engine.mocap.load_sensor_calibration`) its virtual sensors are mounted as measured."""
    clips = shipped_clip_paths(exclude)
    config = GraphConfig(fps=GRAPH_FPS, sensor_names=list(sensor_names))
    motions = [load_clip(path, fps=GRAPH_FPS) for path in clips.values()]
    skeleton = motions[0].skeleton
    placements = standard_placements(skeleton, tuple(sensor_names))
    if calibration is not None:
        placements = placements_from_calibration(placements, calibration)  # ValueError: other joint frames
    cache = graph_cache_path(list(clips.values()), sensor_names, config, cache_dir, calibration)
    if cache.is_file():
        return MotionGraph.load(cache), skeleton, cache
    graph = MotionGraph.build(motions, placements, config)
    cache.parent.mkdir(parents=True, exist_ok=True)
    tmp = cache.with_suffix(".tmp")
    graph.save(tmp)
    tmp.replace(cache)
    return graph, skeleton, cache


def _orientation_calibration(graph: MotionGraph, calibration: SensorCalibrationData | None
                             ) -> OrientationCalibration | None:
    """The record's orientation calibration of the graph's sensors, in the graph's order (None without one)."""
    return None if calibration is None else calibration.orientation_calibration(graph.config.sensor_names)


def shipped_spec(exclude: Sequence[str] = (), calibration: SensorCalibrationData | None = None,
                 cache_dir: Path | None = None) -> EngineSpec:
    """The motion-graph engine on the shipped clips (the console's default database), cached."""
    graph, skeleton, cache = load_or_build_graph(exclude=exclude, calibration=calibration, cache_dir=cache_dir)
    return motion_graph_spec(graph, f"shipped CMU clips ({cache.name})", skeleton,
                             orientation_calibration=_orientation_calibration(graph, calibration))


def build_spec(motions: Sequence[Motion], database: str) -> EngineSpec:
    """The motion-graph engine on a graph built from ``motions`` at the seed-000 placements."""
    config = GraphConfig(fps=float(motions[0].fps), sensor_names=list(SEED000_SENSORS))
    graph = MotionGraph.build(list(motions), standard_placements(motions[0].skeleton, SEED000_SENSORS), config)
    return motion_graph_spec(graph, database, motions[0].skeleton)


# `load_spec` turns each reading into the graph's nominal sensor frames by the record.
LOADED_DATABASE_TAKES_CALIBRATION = True


def load_spec(path: str | Path, calibration: SensorCalibrationData | None = None) -> EngineSpec:
    """The motion-graph engine on a graph file from `courtside build-graph` with a record's calibration applied
    as `courtside synthesize --calibration` applies it: the orientation calibration poses the segments, the
    mounting rotations turn each frame's readings into the graph's nominal sensor frames (a record made for
    another skeleton's joint frames is refused)."""
    from .calibrated_input import correction_matrices

    graph = MotionGraph.load(path)
    corrections = None
    if calibration is not None and graph.skeleton is not None:
        corrections = correction_matrices(graph.skeleton, list(graph.config.sensor_names), calibration)
    return motion_graph_spec(graph, path, orientation_calibration=_orientation_calibration(graph, calibration),
                             reading_corrections=corrections)
