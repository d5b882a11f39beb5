"""Which live sensor feeds each graph sensor: the calibration record's assignment, else the chosen station."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from engine.mocap import SEED000_SENSORS, SensorCalibrationData
from gui.engine_link import worn_sensors


def record(assign: dict[str, str]) -> SensorCalibrationData:
    return SensorCalibrationData(Path("take01.calibration.json"), rotations={s: np.eye(3) for s in assign},
                                 sensor_ids=dict(assign))


def test_without_a_record_sensor_i_of_the_station_is_graph_sensor_i():
    keys, notes = worn_sensors(SEED000_SENSORS, "st2")
    assert keys == [("st2", i) for i in range(len(SEED000_SENSORS))] and notes == []


def test_the_record_assignment_wins_even_across_stations():
    assign = {name: f"st{1 + i % 2}/{5 - i}" for i, name in enumerate(SEED000_SENSORS)}  # shuffled, two stations
    keys, notes = worn_sensors(SEED000_SENSORS, "st9", record(assign))
    assert keys == [(f"st{1 + i % 2}", 5 - i) for i in range(len(SEED000_SENSORS))] and notes == []


def test_segments_missing_from_the_record_fall_back_to_the_station_and_say_so():
    keys, notes = worn_sensors(SEED000_SENSORS[:3], "st1", record({SEED000_SENSORS[1]: "st3/0"}))
    assert keys == [("st1", 0), ("st3", 0), ("st1", 2)]
    assert len(notes) == 2 and all("assumed st1/" in n for n in notes)
    keys, notes = worn_sensors(SEED000_SENSORS[:3], None, record({SEED000_SENSORS[1]: "st3/0"}))
    assert keys is None and "no sensor" in notes[-1]


def test_bad_sensor_ids_and_double_use_are_refused_naming_the_record():
    with pytest.raises(ValueError, match="take01.calibration.json.*'left_forearm'"):
        worn_sensors(["left_forearm"], "st1", record({"left_forearm": "forearm-sensor"}))
    with pytest.raises(ValueError, match="two segments"):
        worn_sensors(SEED000_SENSORS[:2], "st1", record({SEED000_SENSORS[1]: "st1/0"}))


def test_a_source_naming_its_sensors_maps_them_by_placement_in_any_column_order():
    """An imported IMU file played back: its columns in the user's order, named by placement; a `courtside
    calibrate` record of it names the sensors by placement too. Names beat column positions."""
    placements = {("imported", k): name for k, name in enumerate(reversed(SEED000_SENSORS))}
    n = len(SEED000_SENSORS)
    expected = [("imported", n - 1 - i) for i in range(n)]
    assert worn_sensors(SEED000_SENSORS, "imported", None, placements) == (expected, [])
    by_name = record({name: name for name in SEED000_SENSORS})
    assert worn_sensors(SEED000_SENSORS, "imported", by_name, placements) == (expected, [])
    with pytest.raises(ValueError, match="take01.calibration.json.*'left_forearm'.*nor a sensor of the take"):
        worn_sensors(["left_forearm"], "imported", record({"left_forearm": "forearm-sensor"}), placements)


def test_a_record_of_an_imported_device_file_names_its_sensors_by_the_device_s_labels():
    """`courtside calibrate` of an Xsens import writes each sensor's device id; the playback knows both names."""
    placements = {("imported", k): name for k, name in enumerate(SEED000_SENSORS)}
    labels = {("imported", k): f"00B4{k:04d}" for k in range(len(SEED000_SENSORS))}
    by_device = record({name: f"00B4{len(SEED000_SENSORS) - 1 - k:04d}" for k, name in enumerate(SEED000_SENSORS)})
    keys, notes = worn_sensors(SEED000_SENSORS, "imported", by_device, placements, labels)
    assert keys == [("imported", len(SEED000_SENSORS) - 1 - k) for k in range(len(SEED000_SENSORS))] and not notes
