"""A take's readings turned into the frames of the graph's nominally mounted virtual sensors.

Why here and not a rebuilt graph: a sensor-calibration record (the live wizard's or `courtside calibrate`'s) says
how each real sensor sits on its segment; rotating the readings by ``R_nominalᵀ R_measured``
(engine.mocap.reading_corrections) makes them what the graph's virtual sensors would read, so one graph serves
every subject and strapping."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from engine.mocap import load_sensor_calibration, reading_corrections, standard_placements

from .viterbi import Observations


def _column_corrections(skeleton, sensor_names: list[str], indices: tuple[int, ...], record: str | Path
                        ) -> dict[int, np.ndarray]:
    """Observation column -> the rotation taking its sensor's readings into the nominal frame (calibrated
    sensors only). ValueError when the record was made for another skeleton's joint frames."""
    corrections = reading_corrections(standard_placements(skeleton, sensor_names), load_sensor_calibration(record))
    return {column: corrections[sensor_names[g]] for column, g in enumerate(indices) if sensor_names[g] in corrections}


def calibrated_observations(obs: Observations, skeleton, sensor_names: list[str], record: str | Path) -> Observations:
    """``obs`` with each calibrated sensor's acc column rotated into its nominal frame (others unchanged).
    ValueError when the record was made for another skeleton's joint frames."""
    if obs.acc_g is None:
        return obs
    indices = obs.sensor_indices if obs.sensor_indices is not None else tuple(range(obs.acc_g.shape[1]))
    acc = np.array(obs.acc_g, float)
    for column, c in _column_corrections(skeleton, sensor_names, indices, record).items():
        acc[:, column] = acc[:, column] @ c.T
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
        samples[key] = (t, acc @ c.T, *channels)
    return replace(take, obs=obs, streams=replace(take.streams, samples=samples))
