"""Which synthesis engines exist: one table from engine name to the engine package's adapter module.

Adding an engine is one package plus one `register` line. The adapter module (``engine/<x>/online_engine.py``)
exports three functions, imported only when the engine is used (the gateway and the console's start do not pay
for engines nobody runs):

* ``build_spec(motions, database) -> EngineSpec``: the database builder — the engine on training clips
  (`engine.mocap.Motion`s at one rate; ``database`` names them for the status bar); evaluation builds every
  engine this way on the clips a take is held out of;
* ``shipped_spec(exclude, calibration) -> EngineSpec``: the engine on the clips the project ships (the console's
  default database), minus the ``exclude`` clip names, with a sensor-calibration record or None;
* ``load_spec(path, calibration) -> EngineSpec``: the engine on a database file, with a sensor-calibration record
  or None (what of it applies to a database already built; None: the engine has no file format);
* with a ``load_spec``, ``LOADED_DATABASE_TAKES_CALIBRATION: bool``: whether that database's virtual sensors take
  the record's mountings (a motion graph re-derives them) or keep those it was built with (the console then says
  so).

The console (`engine.stream.databases.engine_spec`), `courtside synthesize --engine` and `courtside
reconstruct --evaluate --engines` all look engines up here; the names are the same everywhere."""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from types import ModuleType

from engine.errors import CourtsideError


@dataclass(frozen=True)
class EngineEntry:
    """One registered engine: its name and its adapter module (a dotted name, imported on first use, or the
    module itself)."""

    name: str
    adapter: str | ModuleType

    def module(self) -> ModuleType:
        return importlib.import_module(self.adapter) if isinstance(self.adapter, str) else self.adapter


_ENGINES: dict[str, EngineEntry] = {}


def register(name: str, adapter: str | ModuleType) -> EngineEntry:
    """Add (or replace) an engine; returns its entry."""
    _ENGINES[name] = EngineEntry(name, adapter)
    return _ENGINES[name]


def unregister(name: str) -> None:
    """Remove an engine (a test's toy engine)."""
    _ENGINES.pop(name, None)


def engine_names() -> tuple[str, ...]:
    """Every registered engine's name, in registration order."""
    return tuple(_ENGINES)


def engine_entry(name: str) -> EngineEntry:
    """The entry of ``name``; an unknown name is one line naming the known ones."""
    if name not in _ENGINES:
        raise CourtsideError(f"unknown engine {name!r} (known: {', '.join(_ENGINES)})")
    return _ENGINES[name]


def adapter(name: str) -> ModuleType:
    """The adapter module of ``name`` (module doc): ``build_spec``, ``shipped_spec``, ``load_spec``."""
    return engine_entry(name).module()


register("motion-graph", "engine.graph.online_engine")
register("olng", "engine.olng.online_engine")
register("hmm", "engine.hmm.online_engine")
