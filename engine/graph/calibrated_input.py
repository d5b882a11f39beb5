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


def calibrated_observations(obs: Observations, skeleton, sensor_names: list[str], record: str | Path) -> Observations:
    """``obs`` with each calibrated sensor's acc column rotated into its nominal frame (others unchanged).
    ValueError when the record was made for another skeleton's joint frames."""
    if obs.acc_g is None:
        return obs
    corrections = reading_corrections(standard_placements(skeleton, sensor_names), load_sensor_calibration(record))
    indices = obs.sensor_indices if obs.sensor_indices is not None else tuple(range(obs.acc_g.shape[1]))
    acc = np.array(obs.acc_g, float)
    for column, graph_index in enumerate(indices):
        c = corrections.get(sensor_names[graph_index])
        if c is not None:
            acc[:, column] = acc[:, column] @ c.T
    return replace(obs, acc_g=acc)
