"""The databases the console and the demo run on when the operator names none, and the choice of engine.

Every engine's default database is built from the clips the project ships (`shipped_motions`: CMU subject 16,
minus any held-out clips the demo replays, so the demo never synthesises a motion it has seen), by the engine's
own adapter (`engine.stream.registry`; the motion graph caches its graph, keyed by the clips, sensors, config and
calibrated rotations). `engine_spec` turns the operator's choice (``--engine``, ``--graph``, ``--kb``) or the
number of worn sensors (`engine.stream.engines.default_engine`) into an `EngineSpec`."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .engines import EngineMismatchError, EngineSpec, default_engine
from .registry import adapter

GRAPH_FPS = 30.0  # the rate the shipped clips are loaded at for every engine's default database
SHIPPED_PREFIX = "16_"  # the shipped clips of one skeleton topology (CMU subject 16)


def shipped_clip_paths(exclude: Sequence[str] = ()) -> dict[str, Path]:
    """The shipped subject-16 clip files by name, minus ``exclude`` (clip names)."""
    from engine.mocap import sample_clips

    clips = {name: path for name, path in sample_clips().items()
             if name.startswith(SHIPPED_PREFIX) and name not in exclude}
    if not clips:
        raise ValueError("no shipped clips left to build a database from")
    return clips


def shipped_motions(exclude: Sequence[str] = ()) -> list[Any]:
    """The shipped subject-16 clips (minus ``exclude``) as `engine.mocap.Motion`s at `GRAPH_FPS`."""
    from engine.mocap import load_clip

    return [load_clip(path, fps=GRAPH_FPS) for path in shipped_clip_paths(exclude).values()]


def engine_spec(engine: str | None, *, graph_path: Path | None = None, kb_path: Path | None = None,
                n_worn: int = 6, exclude: Sequence[str] = (), calibration: Any = None) -> tuple[EngineSpec, list[str]]:
    """The engine the console runs, and notes on what was assumed.

    ``engine`` None: a --graph file means the motion graph, a --kb file the OLNG, otherwise
    `engine.stream.default_engine` of the number of worn sensors; for one sensor that is the HMM, on an
    accelerometer-only model trained from the shipped clips at the placement the calibration record names (else
    the right foot, seed 004's). A database file goes to the engine it belongs to; an engine without a file
    format refuses one."""
    files = {"motion-graph": graph_path, "olng": kb_path}
    notes: list[str] = []
    if engine is None:
        engine = "motion-graph" if graph_path else "olng" if kb_path else default_engine(n_worn)
        notes.append(f"engine {engine} (default for {n_worn} worn sensors)")
    module = adapter(engine)
    if module.load_spec is None:
        if graph_path is not None or kb_path is not None:
            raise EngineMismatchError(f"--engine {engine} trains its model from the shipped clips; --graph and --kb "
                                      "are databases of the motion graph and the OLNG")
        return module.shipped_spec(exclude, calibration), notes
    path = files.get(engine)
    if path is None:
        return module.shipped_spec(exclude, calibration), notes
    if calibration is not None and not module.LOADED_DATABASE_TAKES_CALIBRATION:
        notes.append(f"{path}: the database's virtual sensors keep the mounting it was built with (build it with "
                     "the calibration record, e.g. `courtside build-graph --calibration`, to use its rotations)")
    return module.load_spec(path, calibration), notes
