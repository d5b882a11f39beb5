"""The console on an IMU file the user imported (issue 29: "for the file and the console alike"): a vendor-style
CSV of six strapped IMUs (specific force in m/s², the vendor's quaternion; a held-out clip after a 1.5-s A-pose)
-> `courtside import-imu` -> `courtside calibrate --graph` -> `courtside console --playback take.npz --graph
--calibration --save-poses` (the play button pressed) shows, frame for frame and bit for bit, the poses
`courtside synthesize --lag` writes for the same file and record. The record names the sensors by placement,
which the playback maps; a console without the record maps them by the file's names alike."""
from __future__ import annotations

import numpy as np
import pytest

from bench.bench_real_recording import run, simulate_recording, write_csv
from engine.evaluation.takes import chain_clips
from engine.graph.config import GraphConfig
from engine.graph.graph import MotionGraph
from engine.mocap import load_database, load_sensor_calibration, sample_clips, standard_placements
from engine.stream.databases import engine_spec
from engine.stream.poses_file import load_poses
from gui.cli import console_main
from gui.main_window import ConsoleWindow
from gui.playback import IMPORTED_STATION, Playback
from PySide6 import QtCore

LAG_S = 0.5


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    """(graph file, imported take, calibration record): the graph of every shipped subject-16 clip but the one
    the take acts."""
    work = tmp_path_factory.mktemp("imported")
    motions = load_database([p for name, p in sorted(sample_clips().items()) if name.startswith("16_")], fps=30.0)
    graph = MotionGraph.build(motions[1:], standard_placements(motions[0].skeleton), GraphConfig())
    graph.save(work / "graph.npz")
    take = chain_clips(motions, [0], [m.name for m in motions], max_clip_s=4.0)
    recording = simulate_recording(take, "apose:70", "random", "9axis", np.random.default_rng(5))
    csv_args = write_csv(work / "take.csv", recording)
    run(["import-imu", str(work / "take.csv"), "--format", "csv", *csv_args, "-o", str(work / "take.npz"),
         "--quiet"])
    run(["calibrate", str(work / "take.npz"), "--graph", str(work / "graph.npz"), "-o", str(work / "rec.json")])
    return work / "graph.npz", work / "take.npz", work / "rec.json"


def _console_poses(qapp, out, *args: str) -> np.ndarray:
    def press_play() -> None:  # the operator's play button, once the console's window is up
        for window in qapp.topLevelWidgets():
            if isinstance(window, ConsoleWindow):
                window.playbar.play_button.setChecked(True)

    QtCore.QTimer.singleShot(500, press_play)
    assert console_main([*args, "--lag", str(LAG_S), "--duration", "8", "--save-poses", str(out)]) == 0
    return load_poses(out).joint_positions_m


@pytest.mark.parametrize("with_record", [True, False])
def test_the_console_shows_what_synthesize_writes_for_an_imported_take(qapp, imported, tmp_path, with_record):
    graph, take, record = imported
    calibration = ["--calibration", str(record)] if with_record else []
    run(["synthesize", "--graph", str(graph), "--input", str(take), "-o", str(tmp_path / "out.bvh"), "--lag",
         str(LAG_S), "--save-poses", str(tmp_path / "file.npz"), "--quiet", *calibration])
    offline = load_poses(tmp_path / "file.npz").joint_positions_m
    live = _console_poses(qapp, tmp_path / "console.npz", "--playback", str(take), "--graph", str(graph),
                          *calibration)
    # the console stops before the engine's last lag is decided; every frame it decided is the file's
    assert 0.7 * len(offline) <= len(live) <= len(offline)
    np.testing.assert_array_equal(live, offline[:len(live)])


def test_an_imported_take_plays_as_one_station_named_by_placement(imported):
    _, take, _ = imported
    playback = Playback(take)
    assert {key[0] for key in playback.samples} == {IMPORTED_STATION}
    assert [playback.placements[key] for key in sorted(playback.samples)] == [
        "left_forearm", "right_forearm", "left_shin", "right_shin", "lower_back", "chest"]
    assert all("quat_wxyz" in arrays for arrays in playback.samples.values())
    # its first reading held half a frame before 0 s (as `synthesize` resamples it), whatever the engine's rate
    assert playback.t_start_s == pytest.approx(-1.0 / 60.0, abs=1e-4)
    assert playback.for_frame_rate(120.0).t_start_s == pytest.approx(playback.t_start_s, abs=1e-4)
    assert playback.for_frame_rate(10.0).t_start_s == pytest.approx(-0.05)


def test_a_file_that_is_no_imported_take_is_refused_naming_it(tmp_path):
    path = tmp_path / "export.npz"
    np.savez(path, **{"st1/0/acc_g": np.zeros((10, 3))})
    with pytest.raises(ValueError, match=r"export\.npz.*not an import-imu take"):
        Playback(path)


def test_the_console_does_not_claim_a_graph_file_ignores_the_record(imported):
    """`engine_spec` on a graph file with a record: the console's engine takes the record's mountings
    (`load_spec`), so no note says the database keeps the mounting it was built with (the OLNG's knowledge base
    does keep it, and still says so)."""
    graph, _, record = imported
    spec, notes = engine_spec("motion-graph", graph_path=graph, calibration=load_sensor_calibration(record))
    assert spec.name == "motion-graph" and not any("keep the mounting" in note for note in notes)


def test_a_playback_for_another_frame_rate_is_the_file_read_at_that_rate(imported):
    """`for_frame_rate` resamples the arrays read once; it must give what reading the file at that rate gives,
    and leave the 30-Hz playback as it was."""
    _, take, _ = imported
    playback = Playback(take)
    before = {key: {name: values.copy() for name, values in arrays.items()} for key, arrays in playback.samples.items()}
    for rate_hz in (10.0, 120.0):
        resampled, read = playback.for_frame_rate(rate_hz), Playback(take, rate_hz)
        assert resampled.samples.keys() == read.samples.keys()
        for key, arrays in read.samples.items():
            assert resampled.samples[key].keys() == arrays.keys()
            for name, values in arrays.items():
                np.testing.assert_array_equal(resampled.samples[key][name], values)
        assert (resampled.t_start_s, resampled.t_end_s) == (read.t_start_s, read.t_end_s)
    for key, arrays in before.items():
        for name, values in arrays.items():
            np.testing.assert_array_equal(playback.samples[key][name], values)
