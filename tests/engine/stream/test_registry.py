"""Adding an engine is one package plus one registry line: a toy fourth engine (`toy_engine.py`), registered
here, runs through `courtside evaluate`, `courtside synthesize` and the console's live path, and its poses
(known exactly from its inputs) come out of each."""
from __future__ import annotations

import time

import numpy as np
import pytest

from engine.stream import engine_names, register
from engine.stream.databases import engine_spec
from engine.stream.poses_file import load_poses
from engine.stream.registry import unregister
from gateway.cli import main as courtside

from tests.engine.evaluation.test_cli import table_rows

from . import toy_engine


@pytest.fixture()
def toy():
    register("toy", toy_engine)  # the one line a new engine needs
    yield "toy"
    unregister("toy")


def test_the_three_engines_are_registered_under_one_set_of_names():
    assert engine_names()[:3] == ("motion-graph", "olng", "hmm")


def test_toy_engine_runs_through_evaluate(toy, capsys):
    assert courtside(["evaluate", "--protocol", "chained", "--sample", "--takes", "1", "--take-seconds", "3",
                      "--engines", "toy", "--sensor-sets", "6"]) == 0
    out = capsys.readouterr().out
    rows = {camera: values for (engine, sensors, camera), values in table_rows(out).items()
            if (engine, sensors) == ("toy", "2")}
    assert set(rows) == {"yes", "no"}, out
    # column 3: root position error (cm). With the camera the toy stands on the fused camera track (5 cm noise);
    # without it, at the origin, metres from where the take's performer walks.
    assert rows["yes"][3] < 10.0 < rows["no"][3], rows


def test_toy_engine_runs_through_synthesize(toy, tmp_path):
    n = 40
    acc = np.zeros((n, 2, 3))
    acc[:, 0, 0], acc[:, 1, 0] = 0.3, 0.7  # constant: the frame clock's box filter keeps them exactly
    t = np.arange(n) / 30.0
    pos = np.c_[2 * t, 1.5 * t - 3]  # linear: the fix at any frame time is known
    take = tmp_path / "take.npz"
    np.savez(take, acc_g=acc, fps=30.0, position_m=pos,
             sensor_names=np.array(["right_forearm", "left_forearm"]))  # columns in the other order
    out = tmp_path / "toy.npz"
    assert courtside(["synthesize", "--engine", "toy", "--input", str(take), "-o", str(out)]) == 0
    poses = load_poses(out)
    assert poses.meta["engine"] == "toy"
    assert len(poses.frame) >= n - 2
    root = poses.joint_positions_m[:, 0]
    np.testing.assert_allclose(root[:, [0, 2]], np.c_[2 * poses.t_s, 1.5 * poses.t_s - 3], atol=1e-9)
    np.testing.assert_allclose(root[:, 1], 0.7)  # left_forearm (the toy's column 0) is the file's column 1


def test_toy_engine_runs_through_the_console_path(toy):
    from gui.cli import _console_parser
    from gui.engine_link import synthesis_setup
    from gui.synthesis import SynthesisWorker

    assert _console_parser().parse_args(["--engine", "toy"]).engine == "toy"
    spec, _ = engine_spec("toy", n_worn=2)
    assert spec.name == "toy" and spec.inputs == ("acc",)
    sensors = [("st0", 0), ("st0", 1)]
    worker = SynthesisWorker(synthesis_setup(spec, sensors, lag_s=0.5), keep_poses=True)
    worker.start()
    try:
        t = 50.0 + np.arange(300) / 100.0
        # the camera's fixes first: a frame decided before any fix has arrived has none (a race CI caught)
        for tc in np.arange(50.0, 53.0, 1 / 12):
            worker.add_camera(float(tc), [1.0, -2.0], None)
        for k, key in enumerate(sensors):
            worker.add_samples(key, t, np.tile([0.25 + k, 0.0, 1.0], (len(t), 1)))
        deadline = time.monotonic() + 20
        while worker.stats.frames_in < 60 and time.monotonic() < deadline:
            time.sleep(0.02)
    finally:
        worker.stop()
        worker.join(timeout=5)
    assert worker.stats.error == ""
    _, poses = worker.poses()
    assert len(poses) >= 60
    roots = np.array([p.joint_positions_m[0] for p in poses])
    np.testing.assert_allclose(roots, np.tile([1.0, 0.25, -2.0], (len(poses), 1)))
