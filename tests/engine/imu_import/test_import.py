"""Known-answer imports: files written in each real format from virtual sensors must come back as the same
specific force (g, sensor frame), orientation and gyro, on the same time grid."""
from __future__ import annotations

import numpy as np
import pytest

from engine.errors import CourtsideError, MalformedFileError
from engine.imu_import import DetectionError, assemble, read_generic_csv, read_xsens, read_ximu3

from bench.support.imu_formats import write_generic_csv, write_mt_exports, write_mvnx, write_ximu3_logger


def _match(take, truth, acc_tol_g=2e-5, quat_tol=1e-5):
    idx = [truth.names.index(n) for n in take.sensor_names]
    assert take.fps == pytest.approx(truth.fps)
    assert take.acc_g.shape == truth.acc_g[:, idx].shape
    assert np.abs(take.acc_g - truth.acc_g[:, idx]).max() < acc_tol_g
    if take.quat_wxyz is not None:
        dots = np.abs(np.sum(take.quat_wxyz * truth.quat_z_up()[:, idx], axis=-1))
        assert np.abs(dots - 1).max() < quat_tol
    return idx


@pytest.mark.parametrize("units,order,delim,time_unit", [("m/s2", "xyzw", ",", "ms"), ("g", "wxyz", "\t", "s"),
                                                          ("mg", "xyzw", ";", "us")])
def test_generic_csv_units_and_quaternion_order_detected(tmp_path, walk_truth, units, order, delim, time_unit):
    cols = write_generic_csv(tmp_path / "take.csv", walk_truth, units, order, delim, time_unit)
    streams = read_generic_csv(tmp_path / "take.csv", {n: c[0] for n, c in cols.items()},
                               {n: c[1] for n, c in cols.items()}, time_column="time", time_unit=time_unit)
    take = assemble(streams, "csv")
    _match(take, walk_truth)
    assert {s["units"] for s in take.report["sensors"].values()} == {units}
    assert take.report["quaternions"]["order"] == order
    assert take.report["quaternions"]["sensor_to_world"] is True
    np.testing.assert_allclose(np.abs(take.report["quaternions"]["world_up"]), [0, 0, 1], atol=0.02)


def test_metres_per_second_squared_is_never_taken_as_g(tmp_path, walk_truth):
    cols = write_generic_csv(tmp_path / "take.csv", walk_truth, "m/s2")
    acc = {n: c[0] for n, c in cols.items()}
    streams = read_generic_csv(tmp_path / "take.csv", acc, time_column="time", time_unit="ms")
    with pytest.raises(DetectionError, match=r"stated unit g but .*the data is in m/s2"):
        assemble(streams, "csv", units="g")
    take = assemble(streams, "csv", units="m/s2")  # stated and right: converted
    _match(take, walk_truth)


def test_wrong_quaternion_columns_and_stated_order_are_refused(tmp_path, walk_truth):
    cols = write_generic_csv(tmp_path / "take.csv", walk_truth, "g", "xyzw")
    acc = {n: c[0] for n, c in cols.items()}
    first, (_, q_cols) = next(iter(cols.items()))
    not_quat = {first: [*q_cols[:3], "time"]}  # three of the four, and the time
    with pytest.raises(MalformedFileError, match=r"take.csv, line 2: .* is not a unit quaternion"):
        assemble(read_generic_csv(tmp_path / "take.csv", acc, not_quat, time_column="time", time_unit="ms"), "csv")
    streams = read_generic_csv(tmp_path / "take.csv", acc, {n: c[1] for n, c in cols.items()}, time_column="time",
                               time_unit="ms")
    forced = assemble(streams, "csv", quat_order="wxyz")  # a wrong stated order is obeyed, and it shows
    assert forced.report["quaternions"]["score"] < 0.9 * assemble(streams, "csv").report["quaternions"]["score"]


def test_ximu3_logger_folder(tmp_path, walk_truth):
    serials = [f"{0x65577B40 + k:08X}" for k in range(len(walk_truth.names))]
    root = write_ximu3_logger(tmp_path / "Logged Data", walk_truth, serials, walk_truth.names,
                              [1_000_000 + 7_919 * k for k in range(len(serials))])
    streams, ignored = read_ximu3(root)
    assert ignored == []
    take = assemble(streams, "ximu3")
    idx = _match(take, walk_truth, acc_tol_g=1e-6, quat_tol=2e-3)  # Quaternion.csv at half rate: interpolated
    np.testing.assert_allclose(take.gyro_rps, walk_truth.gyro_rps[:, idx], atol=1e-7)
    assert take.report["sensors"][streams[0].label]["units_detected"] == "g"


def test_ximu3_devices_with_factory_names_need_a_map(tmp_path, walk_truth):
    root = write_ximu3_logger(tmp_path / "rec", walk_truth, ["0000AAAA", "0000BBBB"] + [f"0000CC{k:02X}" for k in range(5)],
                              ["x-IMU3"] * 7, [0] * 7)
    with pytest.raises(CourtsideError, match="--sensor-map"):
        read_ximu3(root)
    streams, ignored = read_ximu3(root, {"0000AAAA": walk_truth.names[0], "0000BBBB": walk_truth.names[1]})
    assert len(ignored) == 5
    _match(assemble(streams, "ximu3"), walk_truth, acc_tol_g=1e-6, quat_tol=2e-3)


def test_mvnx_free_acceleration_back_to_specific_force(tmp_path, walk_truth):
    write_mvnx(tmp_path / "take.mvnx", walk_truth)
    streams, ignored = read_xsens(tmp_path / "take.mvnx")
    assert ignored == ["Head"]
    take = assemble(streams, "xsens")
    _match(take, walk_truth, acc_tol_g=1e-4)  # 6-decimal quaternions rotate readings of up to ~25 g
    assert {s["units_detected"] for s in take.report["sensors"].values()} == {"m/s2"}


def test_mt_manager_text_exports(tmp_path, walk_truth):
    ids = [f"00B42D{k:02X}" for k in range(len(walk_truth.names))]
    write_mt_exports(tmp_path / "mt", walk_truth, ids)
    streams, _ = read_xsens(tmp_path / "mt", dict(zip(ids, walk_truth.names)))
    take = assemble(streams, "xsens")
    idx = _match(take, walk_truth, acc_tol_g=1e-6)
    np.testing.assert_allclose(take.gyro_rps, walk_truth.gyro_rps[:, idx], atol=1e-6)


def test_bad_files_name_file_and_line(tmp_path, walk_truth):
    cols = write_generic_csv(tmp_path / "take.csv", walk_truth, "g")
    lines = (tmp_path / "take.csv").read_text().splitlines()
    lines[5] = lines[5].replace(lines[5].split(",")[2], "oops", 1)
    (tmp_path / "bad.csv").write_text("\n".join(lines))
    with pytest.raises(MalformedFileError, match=r"bad\.csv, line 6: column .* 'oops' is not a number"):
        read_generic_csv(tmp_path / "bad.csv", {n: c[0] for n, c in cols.items()}, time_column="time")
    with pytest.raises(MalformedFileError, match="no column 'nope'"):
        read_generic_csv(tmp_path / "take.csv", {"chest": ["nope", "1", "2"]}, time_column="time")
    write_mvnx(tmp_path / "t.mvnx", walk_truth)
    text = (tmp_path / "t.mvnx").read_text()
    (tmp_path / "cut.mvnx").write_text(text[: len(text) // 2])
    with pytest.raises(MalformedFileError, match=r"cut\.mvnx, line \d+: not well-formed MVNX"):
        read_xsens(tmp_path / "cut.mvnx")
    with pytest.raises(MalformedFileError, match="no x-IMU3 device folder"):
        read_ximu3(tmp_path)


def test_take_with_a_sensor_the_graph_lacks_still_loads(tmp_path, walk_truth):
    """An imported take holds every mapped sensor (here also right_foot); a six-sensor graph uses its six."""
    from engine.graph.inputs import load_take

    cols = write_generic_csv(tmp_path / "take.csv", walk_truth, "g")
    take = assemble(read_generic_csv(tmp_path / "take.csv", {n: c[0] for n, c in cols.items()}, time_column="time",
                                     time_unit="ms"), "csv")
    take.save(tmp_path / "take.npz")
    graph_sensors = walk_truth.names[:6]
    obs = load_take(tmp_path / "take.npz", graph_sensors, 30.0)
    assert obs.acc_g.shape[1] == 6 and obs.sensor_indices == tuple(range(6))
    with pytest.raises(MalformedFileError, match="do not match"):
        load_take(tmp_path / "take.npz", ["head_top"], 30.0)


def test_synthesis_input_points_a_raw_device_file_to_import_imu(tmp_path, walk_truth):
    """The issue's first stumble: a CSV given to synthesize. The error now says what to do."""
    from engine.graph.inputs import load_take

    write_generic_csv(tmp_path / "take.csv", walk_truth, "m/s2")
    with pytest.raises(MalformedFileError, match="courtside import-imu"):
        load_take(tmp_path / "take.csv", walk_truth.names[:6], 30.0)
