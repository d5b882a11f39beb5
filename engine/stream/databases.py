"""The databases the console and the demo run on when the operator names none, and the choice of engine.

`load_or_build_graph` builds the motion graph from the clips the project ships (`engine.mocap.sample_clips()`,
minus any held-out clips the demo replays, so the demo never synthesises a motion it has seen) and caches it as
.npz keyed by the clip files, sensor names, graph config and calibrated rotations, so a second start only loads
it. With a sensor-calibration record (written by the gateway's calibration workflow) the graph's virtual sensors
use the measured sensor-to-segment rotations (`engine.mocap.placements_from_calibration`); each calibration gets
its own cached graph. `engine_spec` turns the operator's choice (``--engine``, ``--graph``, ``--kb``) or the
number of worn sensors (`engine.stream.engines.default_engine`) into an `EngineSpec`."""
from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from pathlib import Path

from engine.graph.config import GraphConfig
from engine.graph.graph import MotionGraph
from engine.mocap import (SEED000_SENSORS, SensorCalibrationData, Skeleton, default_cache_dir, load_clip,
                          placements_from_calibration, sample_clips, standard_placements)

from .engines import EngineMismatchError, EngineSpec, default_engine, hmm_spec, motion_graph_spec, olng_spec

GRAPH_FPS = 30.0


def graph_cache_path(clip_paths: Sequence[Path], sensor_names: Sequence[str], config: GraphConfig,
                     cache_dir: Path | None = None, calibration: SensorCalibrationData | None = None) -> Path:
    """Cache file name from the clip files' identity (path, size, mtime), sensors, config and the calibrated
    rotations (if any)."""
    parts = [json.dumps(list(sensor_names)), config.to_json()]
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
    clips = {name: path for name, path in sample_clips().items() if name.startswith("16_") and name not in exclude}
    if not clips:
        raise ValueError("no shipped clips left to build a motion graph from")
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


def shipped_graph_spec(exclude: Sequence[str] = (), calibration: SensorCalibrationData | None = None,
                       cache_dir: Path | None = None) -> EngineSpec:
    """The motion-graph engine on the shipped clips (the console's default database), cached."""
    graph, skeleton, cache = load_or_build_graph(exclude=exclude, calibration=calibration, cache_dir=cache_dir)
    return motion_graph_spec(graph, f"shipped CMU clips ({cache.name})", skeleton)


def shipped_olng_spec(exclude: Sequence[str] = ()) -> EngineSpec:
    """The OLNG engine on a knowledge base built from the shipped subject-16 clips (about a second; not cached)."""
    from engine.olng.config import KnowledgeBaseConfig
    from engine.olng.mocap_bridge import build_knowledge_base

    clips = [load_clip(path, fps=GRAPH_FPS) for name, path in sample_clips().items()
             if name.startswith("16_") and name not in exclude]
    return olng_spec(build_knowledge_base(clips, KnowledgeBaseConfig()), "shipped CMU clips")


def shipped_hmm_spec(exclude: Sequence[str] = (), sensor_names: Sequence[str] = ("right_foot",)) -> EngineSpec:
    """The hierarchical HMM trained on the shipped subject-16 clips at ``sensor_names`` (one IMU: seed 004's
    right foot), accelerometer only (the live stream has no gyroscope); trains in a fraction of a second."""
    from engine.hmm.config import HMMConfig
    from engine.hmm.evaluation import train_model

    clips = [load_clip(path, fps=GRAPH_FPS) for name, path in sample_clips().items()
             if name.startswith("16_") and name not in exclude]
    model = train_model(clips, tuple(sensor_names), config=HMMConfig(imu_channels="acc"))
    return hmm_spec(model, "shipped CMU clips, accelerometer-only model", sensor_names, clips[0].skeleton)


def engine_spec(engine: str | None, *, graph_path: Path | None = None, kb_path: Path | None = None,
                n_worn: int = 6, exclude: Sequence[str] = (),
                calibration: SensorCalibrationData | None = None) -> tuple[EngineSpec, list[str]]:
    """The engine the console runs, and notes on what was assumed.

    ``engine`` None: a --graph file means the motion graph, a --kb file the OLNG, otherwise
    `engine.stream.default_engine` of the number of worn sensors; for one sensor that is the HMM, on an
    accelerometer-only model trained from the shipped clips at the placement the calibration record names (else
    the right foot, seed 004's) (`shipped_hmm_spec`)."""
    from engine.olng.knowledge_base import KnowledgeBase

    notes: list[str] = []
    if engine is None:
        engine = "motion-graph" if graph_path else "olng" if kb_path else default_engine(n_worn)
        notes.append(f"engine {engine} (default for {n_worn} worn sensors)")
    if engine == "hmm":
        if graph_path is not None or kb_path is not None:
            raise EngineMismatchError("--engine hmm trains its model from the shipped clips; --graph and --kb "
                                      "are databases of the motion graph and the OLNG")
        worn = tuple(calibration.sensor_ids) if calibration is not None else ()  # segment -> live sensor
        return shipped_hmm_spec(exclude, worn if len(worn) == 1 else ("right_foot",)), notes
    if engine == "olng":
        if kb_path is not None:
            return olng_spec(KnowledgeBase.load(kb_path), kb_path), notes
        return shipped_olng_spec(exclude), notes
    if graph_path is not None:
        if calibration is not None:
            notes.append(f"{graph_path}: the graph's virtual sensors keep the mounting it was built with "
                         "(build it with `courtside build-graph --calibration` to use the record's rotations)")
        return motion_graph_spec(MotionGraph.load(graph_path), graph_path), notes
    return shipped_graph_spec(exclude, calibration), notes
