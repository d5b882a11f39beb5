"""A take's readings turned into the frames of the graph's nominally mounted virtual sensors.

Why here and not a rebuilt graph: a sensor-calibration record (the live wizard's or `courtside calibrate`'s) says
how each real sensor sits on its segment; rotating the readings by ``R_nominalᵀ R_measured``
(engine.mocap.reading_corrections) makes them what the graph's virtual sensors would read, so one graph serves
every subject and strapping. The console's engine on a graph file (`CorrectedReadings`, online_engine.load_spec)
rotates each pushed frame by the same matrices, so a take synthesised with `--calibration` and the console on
the same record give the same poses."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from engine.mocap import SensorCalibrationData, load_sensor_calibration, reading_corrections, standard_placements
from engine.mocap.calibrated import skeleton_identity

from .viterbi import Observations


def rotate_readings(acc_g: np.ndarray, correction: np.ndarray) -> np.ndarray:
    """(..., 3) readings a turned by the rotation C (3, 3), or per sensor (..., S, 3) by (S, 3, 3): C a. One
    elementwise formula for a whole take and for one pushed frame alike, so both give the same floats."""
    return np.sum(np.asarray(acc_g, float)[..., None, :] * correction, axis=-1)


def _column_corrections(skeleton, sensor_names: list[str], indices: tuple[int, ...], record: str | Path
                        ) -> dict[int, np.ndarray]:
    """Observation column -> the rotation taking its sensor's readings into the nominal frame (calibrated
    sensors only; a record made for other joint frames converted through its straps). MalformedFileError naming
    both skeletons when it cannot be."""
    corrections = reading_corrections(standard_placements(skeleton, sensor_names), load_sensor_calibration(record),
                                      skeleton_identity(skeleton, "the graph's skeleton"))
    return {column: corrections[sensor_names[g]] for column, g in enumerate(indices) if sensor_names[g] in corrections}


def calibrated_observations(obs: Observations, skeleton, sensor_names: list[str], record: str | Path) -> Observations:
    """``obs`` with each calibrated sensor's acc column rotated into its nominal frame (others unchanged).
    ValueError when the record was made for another skeleton's joint frames."""
    if obs.acc_g is None:
        return obs
    indices = obs.sensor_indices if obs.sensor_indices is not None else tuple(range(obs.acc_g.shape[1]))
    acc = np.array(obs.acc_g, float)
    for column, c in _column_corrections(skeleton, sensor_names, indices, record).items():
        acc[:, column] = rotate_readings(acc[:, column], c)
    return replace(obs, acc_g=acc)


def calibrated_take(take, skeleton, sensor_names: list[str], record: str | Path):
    """A `engine.graph.inputs.TakeFrames` with its observations and, for a gateway take, its raw recorded samples
    rotated alike (the fixed-lag path resamples those itself: a rotation commutes with the box filter)."""
    obs = calibrated_observations(take.obs, skeleton, sensor_names, record)
    if take.streams is None or obs.acc_g is None:
        return replace(take, obs=obs)
    indices = obs.sensor_indices if obs.sensor_indices is not None else tuple(range(obs.acc_g.shape[1]))
    samples = dict(take.streams.samples)
    for column, c in _column_corrections(skeleton, sensor_names, indices, record).items():
        key = take.stream_keys[column]
        t, acc, *channels = samples[key]  # orientation / angular rate, when recorded, pass through
        samples[key] = (t, rotate_readings(acc, c), *channels)
    return replace(take, obs=obs, streams=replace(take.streams, samples=samples))


def correction_matrices(skeleton, sensor_names: list[str], calibration: SensorCalibrationData) -> np.ndarray | None:
    """(S, 3, 3) per graph sensor the rotation its readings take into the nominal frame (identity where the
    record has no mounting), or None when every one is the identity. ValueError (MalformedFileError) when the
    record was made for another skeleton's joint frames."""
    corrections = reading_corrections(standard_placements(skeleton, sensor_names), calibration)
    out = np.stack([corrections.get(name, np.eye(3)) for name in sensor_names])
    return None if np.allclose(out, np.eye(3), atol=1e-12) else out


class CorrectedReadings:
    """An online engine whose pushed accelerations (S, 3) g are first rotated into the graph's nominal sensor
    frames by `correction_matrices` (a = C a_real, per column), as `calibrated_take` rotates a whole take; every
    other call and attribute is the wrapped engine's."""

    def __init__(self, inner: Any, corrections: np.ndarray) -> None:
        self._inner = inner
        self._corrections = np.asarray(corrections, float)

    def push(self, acc_g: np.ndarray | None, *args: Any, **kwargs: Any) -> list:
        if acc_g is not None:
            acc_g = rotate_readings(acc_g, self._corrections)
        return self._inner.push(acc_g, *args, **kwargs)

    def flush(self) -> list:
        return self._inner.flush()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)
