"""The console's glue between live sensors and an engine: which live sensor feeds which engine column
(`worn_sensors`), whether they fit the engine's database (`check_worn_sensors`), the synthesis setup, and which
skeleton segment carries each sensor (for the 3-D health colours). The databases and the choice of engine are the
engine's (`engine.stream.databases`); the synthesis path is `engine.stream`."""
from __future__ import annotations

from collections.abc import Mapping, Sequence

from engine.mocap import SensorCalibrationData, Skeleton, standard_placements
from engine.stream.engines import EngineSpec

from gui.synthesis import SensorKey, SynthesisSetup


def synthesis_setup(spec: EngineSpec, sensors: list[SensorKey], lag_s: float = 0.5) -> SynthesisSetup:
    """Console synthesis with ``spec``; ``sensors[i]`` is the live sensor worn where engine sensor i is."""
    if len(sensors) != len(spec.sensor_names):
        raise ValueError(f"{spec.name} expects {len(spec.sensor_names)} sensors, {len(sensors)} mapped")
    return SynthesisSetup(engine=spec, sensors=list(sensors), lag_s=lag_s)


def worn_sensors(segments: Sequence[str], station: str | None,
                 calibration: SensorCalibrationData | None = None,
                 placements: Mapping[SensorKey, str] | None = None,
                 source_labels: Mapping[SensorKey, str] | None = None) -> tuple[list[SensorKey] | None, list[str]]:
    """Which live sensor each graph sensor is: ``segments[i]`` (the graph's placement names) -> (station, index).

    A calibration record says it per segment (the wizard's assignment, sensor ids ``"<station>/<index>"``), so
    sensors may even sit on different stations; a source that names its sensors (an imported IMU file played
    back: ``placements``, and the device's own ``source_labels``, which `courtside calibrate` of that file writes as
    the ids) maps a record's ids by those names and every segment by its placement; segments neither covers fall
    back to sensor i of ``station``. Returns (keys, notes): keys None if some segment has no sensor; notes say
    what was assumed. A sensor id that is neither ``station/index`` nor a name of the source's raises ValueError
    naming the record."""
    by_placement = {name: key for key, name in (placements or {}).items()}
    named = {**{name: key for key, name in (source_labels or {}).items()}, **by_placement}
    keys: list[SensorKey] = []
    notes: list[str] = []
    for i, segment in enumerate(segments):
        sid = calibration.sensor_ids.get(segment) if calibration is not None else None
        if sid is not None:
            st, _, index = sid.rpartition("/")
            if sid in named:
                keys.append(named[sid])
            elif not st or not index.isdigit():
                raise ValueError(f"{calibration.path}: sensor id {sid!r} on {segment!r} is not '<station>/<index>'"
                                 + (f" nor a sensor of the take ({', '.join(sorted(named))})" if named else ""))
            else:
                keys.append((st, int(index)))
        elif segment in by_placement:
            keys.append(by_placement[segment])
        elif station is not None:
            keys.append((station, i))
            if calibration is not None:
                notes.append(f"{segment}: not in the calibration record, assumed {station}/{i}")
        else:
            notes.append(f"{segment}: no sensor (not in the calibration record and no --synth-station)")
            return None, notes
    if len(set(keys)) < len(keys):
        raise ValueError(f"one live sensor mapped to two segments: {keys}")
    return keys, notes


def sensor_joints(skeleton: Skeleton, sensors: dict[SensorKey, str]) -> dict[SensorKey, int]:
    """Live sensor -> the skeleton joint whose segment carries it, from its standard placement name (the 3-D view
    paints that segment with the sensor's health)."""
    placements = standard_placements(skeleton, tuple(sensors.values()))
    return {key: int(p.joint) for key, p in zip(sensors, placements)}


def check_worn_sensors(spec: EngineSpec, keys: list[SensorKey], stations: list[dict],
                       calibration: SensorCalibrationData | None = None) -> None:
    """Refuse unless every live sensor feeding ``spec`` exists and fits it: the station list (gateway status or a
    take) must have each sensor; its placement (the calibration record's, else the one assumed from the
    engine's column order) must be the engine's, and its nominal rate at least the engine's frame rate."""
    from engine.stream.engines import SensorsMissingError, check_live_sensors

    listed = {(str(st["station"]), int(s["sensor"])): float(s.get("nominal_hz") or 0.0)
              for st in stations for s in st.get("sensors", [])}
    missing = [f"{st}/{i}" for st, i in keys if (st, i) not in listed]
    if missing:
        raise SensorsMissingError(f"{spec.name} needs sensors {', '.join(missing)} for "
                                  f"{', '.join(n for n, k in zip(spec.sensor_names, keys) if f'{k[0]}/{k[1]}' in missing)}"
                                  f"; live: {', '.join(f'{st}/{i}' for st, i in sorted(listed)) or 'none'}")
    by_id = {sid: seg for seg, sid in calibration.sensor_ids.items()} if calibration is not None else {}
    worn = [by_id.get(f"{st}/{i}", name) for (st, i), name in zip(keys, spec.sensor_names)]
    check_live_sensors(spec, worn, [listed[k] for k in keys])
