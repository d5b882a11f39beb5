"""`courtside console --engine/--graph/--kb`: the engine and database follow the worn sensors or the operator's
choice, a database that does not fit the live sensors is refused with a message naming both sides, the status bar
names engine and database, and the 3-D view shows the engine's per-frame confidence."""
from __future__ import annotations

import logging

import numpy as np
import pytest

from engine.stream.engines import EngineMismatchError, check_live_sensors, default_engine
from firmware_protocol.emulator.motion import StillSource
from gui.cli import console_main

SEED000 = ["left_forearm", "right_forearm", "left_shin", "right_shin", "lower_back", "chest"]


def stations(n: int, hz: float = 100.0, name: str = "st1") -> list[dict]:
    """A station list shaped as the gateway's status reports it."""
    return [{"station": name, "sensors": [{"sensor": i, "nominal_hz": hz} for i in range(n)]}]


@pytest.fixture(scope="module")
def wrist_graph(tmp_path_factory):
    """A small real graph built for the seed-003 placements (wrists and ankles) from two shipped clips."""
    from engine.graph.cli import build_graph_main
    from engine.mocap import sample_clips

    path = tmp_path_factory.mktemp("graph") / "wrists.npz"
    clips = [str(sample_clips()[c]) for c in ("16_11", "16_16")]
    assert build_graph_main(clips + ["-o", str(path), "--sensors", "left_wrist", "right_wrist", "left_ankle",
                                     "right_ankle"]) == 0
    return path


def test_default_engine_rule():
    assert [default_engine(n) for n in (1, 2, 4, 6, 11)] == ["hmm", "motion-graph", "olng", "motion-graph",
                                                            "motion-graph"]


def test_live_sensor_check_refuses_count_names_rate_and_missing(wrist_graph):
    from engine.graph.graph import MotionGraph
    from engine.graph.online_engine import motion_graph_spec

    from gui.engine_link import check_worn_sensors

    spec = motion_graph_spec(MotionGraph.load(wrist_graph), wrist_graph)
    keys = [("st1", i) for i in range(4)]
    check_worn_sensors(spec, keys, stations(6))  # fits: 4 sensors at 100 Hz, placements assumed in order
    with pytest.raises(EngineMismatchError, match=r"expects 4 sensors .* 6 are worn"):
        check_live_sensors(spec, SEED000, [100.0] * 6)
    with pytest.raises(EngineMismatchError, match=r"column 0: database 'left_wrist', worn 'left_forearm'"):
        check_live_sensors(spec, SEED000[:4], [100.0] * 4)
    with pytest.raises(EngineMismatchError, match=r"runs at 30 Hz .* left_wrist 20 Hz"):
        check_worn_sensors(spec, keys, stations(6, hz=20.0))
    with pytest.raises(EngineMismatchError, match=r"needs sensors st1/3 for right_ankle; live: st1/0, st1/1, st1/2"):
        check_worn_sensors(spec, keys, stations(3))


def test_console_refuses_a_graph_for_other_placements_than_the_calibration_record(live_gateway, qapp, tmp_path,
                                                                                  wrist_graph, capsys):
    """The record says st1/0..5 are on forearms, shins, back and chest; a graph for wrists/ankles cannot run."""
    import json

    gateway, _ = live_gateway(StillSource(6), 6)
    record = tmp_path / "take.calibration.json"
    record.write_text(json.dumps({"schema": "courtside.sensor_calibration", "schema_version": 1, "sensors": {
        f"st1/{i}": {"segment": seg, "rotation": np.eye(3).tolist(), "gravity_sensor_g": [0, 1, 0],
                     "norm_error_g": 0.0, "correction_deg": 0.0, "passed": True} for i, seg in enumerate(SEED000)}}))
    host, port = gateway.address
    code = console_main(["--connect", f"{host}:{port}", "--graph", str(wrist_graph), "--calibration", str(record),
                         "--synth-station", "st1", "--duration", "1"])
    err = capsys.readouterr().err
    assert code == 2 and "built for other placements" in err and "'left_wrist', worn 'left_forearm'" in err
    assert err.count("\n") == 1  # one line, no traceback


@pytest.mark.parametrize("oriented", [True, False])
def test_status_bar_says_whether_segments_are_posed_with_calibrated_yaw(live_gateway, qapp, tmp_path, wrist_graph,
                                                                        caplog, oriented):
    """`courtside console --calibration REC`: a record that calibrated every worn sensor's orientation (the
    N-pose capture of orientation-capable stations) makes the motion graph pose the worn segments with their yaw
    relative to the pelvis, and the engine label says so; an accelerometer-only record (an old one, or
    accelerometer-only stations) poses by tilt only, said in the label and in a log line."""
    import json

    from engine.mocap.calibrated import orientation_fields
    from engine.stream.poses_file import load_poses

    from engine.graph.graph import MotionGraph
    from engine.mocap import standard_placements

    gateway, _ = live_gateway(StillSource(4), 4)
    names = ["left_wrist", "right_wrist", "left_ankle", "right_ankle"]
    # the nominal mountings of the graph's skeleton (the console turns readings by a record's mountings)
    nominal = {p.name: p.rotation for p in standard_placements(MotionGraph.load(wrist_graph).skeleton, names)}
    record = tmp_path / "take.calibration.json"
    record.write_text(json.dumps({"schema": "courtside.sensor_calibration", "schema_version": 1, "sensors": {
        f"st1/{i}": {"segment": seg, "rotation": nominal[seg].tolist(), "gravity_sensor_g": [0, 1, 0],
                     "norm_error_g": 0.0, "correction_deg": 0.0, "passed": True,
                     **(orientation_fields(0.3 * i, [1.0, 0.0, 0.0, 0.0]) if oriented else {})}
        for i, seg in enumerate(names)}}))
    host, port = gateway.address
    with caplog.at_level(logging.INFO):
        assert console_main(["--connect", f"{host}:{port}", "--graph", str(wrist_graph), "--calibration",
                             str(record), "--duration", "2", "--save-poses", str(tmp_path / "p.npz")]) == 0
    how = "calibrated yaw" if oriented else "tilt only"
    assert f"(4 sensors @ 30 Hz, acc+orientation ({how}))" in caplog.text
    assert ("no orientation calibration in the record" in caplog.text) is not oriented
    assert load_poses(tmp_path / "p.npz").meta["engine_label"].endswith(f"acc+orientation ({how}))")


def test_console_refuses_an_unreadable_graph(live_gateway, qapp, tmp_path, capsys):
    gateway, _ = live_gateway(StillSource(6), 6)
    host, port = gateway.address
    bad = tmp_path / "not-a-graph.npz"
    bad.write_bytes(b"nope")
    assert console_main(["--connect", f"{host}:{port}", "--graph", str(bad), "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert "not-a-graph.npz" in err and "Traceback" not in err


def test_four_worn_sensors_default_to_the_olng_and_the_status_bar_names_it(live_gateway, qapp, tmp_path, caplog):
    gateway, _ = live_gateway(StillSource(4), 4)
    host, port = gateway.address
    with caplog.at_level(logging.INFO, logger="courtside.console"):
        assert console_main(["--connect", f"{host}:{port}", "--duration", "2",
                             "--save-poses", str(tmp_path / "p.npz")]) == 0
    assert "engine olng (default for 4 worn sensors)" in caplog.text
    assert "olng on shipped CMU clips (4 sensors @ 25 Hz, acc+orientation+gyro)" in caplog.text
    from engine.stream.poses_file import load_poses

    saved = load_poses(tmp_path / "p.npz")
    assert saved.meta["engine"] == "olng" and [s["placement"] for s in saved.meta["sensors"]] == [
        "left_wrist", "right_wrist", "left_ankle", "right_ankle"]


def test_one_worn_sensor_defaults_to_the_accelerometer_only_hmm_and_it_runs_live(live_gateway, qapp, tmp_path,
                                                                                caplog):
    """The seed-004 HMM reads acc + gyro and these stations stream no gyroscope: live it runs a model trained on
    accelerometers only (it used to be refused, and a one-sensor court fell back to the motion graph); the spec
    names every channel some model of it reads (the richer models run when a stream brings them)."""
    gateway, _ = live_gateway(StillSource(1), 1)
    host, port = gateway.address
    with caplog.at_level(logging.INFO, logger="courtside.console"):
        assert console_main(["--connect", f"{host}:{port}", "--duration", "3",
                             "--save-poses", str(tmp_path / "p.npz")]) == 0
    assert "engine hmm (default for 1 worn sensors)" in caplog.text
    assert "hmm on shipped CMU clips (1 sensors @ 30 Hz, acc+orientation+gyro)" in caplog.text
    from engine.stream.poses_file import load_poses

    saved = load_poses(tmp_path / "p.npz")
    assert saved.meta["engine"] == "hmm" and [s["placement"] for s in saved.meta["sensors"]] == ["right_foot"]
    assert len(saved.t_s) > 10 and np.isfinite(saved.joint_positions_m).all()


def test_athlete_status_names_engine_and_database(live_gateway, qtbot, wrist_graph):
    from gateway.client import GatewayClient
    from engine.graph.graph import MotionGraph
    from engine.graph.online_engine import motion_graph_spec

    from gui.engine_link import synthesis_setup
    from gui.main_window import ConsoleWindow

    gateway, _ = live_gateway(StillSource(4), 4)
    spec = motion_graph_spec(MotionGraph.load(wrist_graph), wrist_graph)
    with GatewayClient(*gateway.address).connect() as client:
        window = ConsoleWindow(client, synthesis=synthesis_setup(spec, [("st1", i) for i in range(4)]))
        qtbot.addWidget(window)
        try:
            qtbot.waitUntil(lambda: window.worker.stats.frames_in > 0, timeout=10_000)
            window.tick()
            text = window.athlete_status.text("")
            assert f"motion-graph on {wrist_graph} (4 sensors @ 30 Hz, acc+orientation (tilt only))" in text and "lag 0.50 s" in text
        finally:
            window.shutdown()


def test_confidence_tints_the_estimate_towards_grey(qtbot):
    from gui.widgets.skeleton_view import SkeletonView

    from tests.gui.test_skeleton_render import PARENTS, POSE, is_estimate_colour

    view = SkeletonView()
    qtbot.addWidget(view)
    view.resize(480, 320)
    view.show()
    view.set_skeleton(PARENTS)
    view.set_poses(POSE)
    view.set_confidence(1.0)
    assert view.refresh()
    confident = is_estimate_colour(view.last_pixels()).sum()
    view.set_confidence(0.0)
    assert view.refresh()
    img = view.last_pixels()
    r, g, b = (img[..., k].astype(int) for k in range(3))
    grey = (abs(r - g) < 25) & (abs(g - b) < 25) & (r > 60)
    assert confident > 30 and is_estimate_colour(img).sum() < confident / 10 and grey.sum() > 30
    view.set_confidence(None)  # the engine reports none: normal colours
    assert view.refresh() and is_estimate_colour(view.last_pixels()).sum() == confident


def test_a_named_database_with_no_way_to_tell_the_worn_sensors_is_refused(qapp, tmp_path, wrist_graph, capsys):
    """Two stations could carry the wrist graph's four sensors and nothing says which: `--graph` was named, so the
    console refuses in one line naming the candidates and the two ways to say it (before: it ran with synthesis
    off, exit 0, the graph silently unused)."""
    from firmware_protocol.emulator import StationConfig
    from gateway.daemon import Gateway
    from firmware_protocol.emulator.stations import start_emulated_station

    stations_ = [start_emulated_station(StationConfig(station_id=i, n_sensors=n, autostart=True), motion=StillSource(n))
                 for i, n in ((1, 6), (2, 5))]
    gateway = Gateway([s.path for s in stations_], listen=("127.0.0.6", 0), record_dir=tmp_path / "rec").start()
    try:
        host, port = gateway.address
        code = console_main(["--connect", f"{host}:{port}", "--graph", str(wrist_graph), "--duration", "1"])
    finally:
        gateway.stop()
        for s in stations_:
            s.stop()
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "needs 4 worn sensors (left_wrist, right_wrist, left_ankle, right_ankle)" in err
    assert "st1 (6 sensors), st2 (5 sensors)" in err and "--synth-station" in err
