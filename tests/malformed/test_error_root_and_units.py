"""One error root for the project, a valid clip with unknown joint names, and the m/s^2-as-g plausibility
warning (the items of issue 12 that are not "a bad file must give one clear line")."""
from __future__ import annotations

import logging
import subprocess
import sys

import numpy as np
import pytest

from engine.errors import CourtsideError, MalformedFileError

from . import corpus


def _classes():
    from engine.skeleton_fit.gdke import DegenerateFitError
    from firmware_protocol.codec import PayloadError
    from gateway.calibration.errors import CalibrationRecordError
    from gateway.camera.errors import CameraError, CourtCalibrationFileError, FrameSourceError
    from gateway.client import GatewayRequestError
    from gateway.codec import CodecError
    from gateway.links import LinkError
    from gateway.recorder import RecorderRefused, RecordingError
    from gateway.server import RequestError
    from gateway.wire import WireError
    from engine.mocap.roles import UnknownSkeletonError

    # class -> the base it had before (code that catches that base must keep working)
    return {CodecError: ValueError, LinkError: ConnectionError, WireError: ConnectionError,
            RecordingError: ValueError, RecorderRefused: ValueError, CalibrationRecordError: MalformedFileError,
            CameraError: Exception, FrameSourceError: CameraError, CourtCalibrationFileError: CameraError,
            PayloadError: ValueError, DegenerateFitError: ValueError, RequestError: Exception,
            GatewayRequestError: RuntimeError, UnknownSkeletonError: ValueError}


def test_every_deliberate_error_derives_from_the_root_and_keeps_its_base():
    for cls, old_base in _classes().items():
        assert issubclass(cls, CourtsideError), cls
        assert issubclass(cls, old_base), cls
    from gateway.links import LinkError

    assert isinstance(LinkError("x"), OSError)  # the reader's `except OSError` paths still see it


def test_file_errors_carry_path_location_and_problem(tmp_path):
    from gateway.calibration.errors import CalibrationRecordError
    from gateway.camera.errors import CourtCalibrationFileError

    for exc in (CalibrationRecordError(tmp_path / "r.json", "bad"), CourtCalibrationFileError(tmp_path / "c.json", "bad")):
        assert isinstance(exc, MalformedFileError) and exc.problem == "bad" and exc.line is None
        assert str(exc) == f"{exc.path}: bad"


def test_mocap_info_on_a_clip_with_unknown_joint_names(tmp_path):
    text = corpus.valid_bvh_text()
    for i, name in enumerate(sorted({line.split()[1] for line in text.splitlines()
                                     if line.strip().split()[:1] in (["JOINT"], ["ROOT"])}, key=len, reverse=True)):
        text = text.replace(f" {name}\n", f" J{i}\n")
    path = tmp_path / "renamed.bvh"
    path.write_text(text)
    done = subprocess.run([sys.executable, "-m", "engine.mocap", "info", str(path)], capture_output=True, text=True)
    assert done.returncode == 0 and done.stderr == ""
    assert "12 frames at 30 Hz" in done.stdout and "foot contacts and heading: n/a" in done.stdout
    assert "no known naming convention" in done.stdout


@pytest.fixture(scope="module")
def graph_sensors():
    from engine.mocap import SEED000_SENSORS

    return list(SEED000_SENSORS)


def test_accelerations_in_m_per_s2_are_flagged(tmp_path, caplog, graph_sensors):
    from engine.graph.inputs import load_take

    take = corpus.take_arrays()
    np.savez(tmp_path / "g_units.npz", acc_g=take["acc_g"], fps=take["fps"])
    np.savez(tmp_path / "si_units.npz", acc_g=take["acc_g"] * 9.80665, fps=take["fps"])
    with caplog.at_level(logging.WARNING):
        load_take(tmp_path / "g_units.npz", graph_sensors, 30.0)
    assert not caplog.records
    with caplog.at_level(logging.WARNING):
        obs = load_take(tmp_path / "si_units.npz", graph_sensors, 30.0)
    assert obs.acc_g is not None
    (record,) = caplog.records
    assert "si_units.npz" in record.getMessage() and "m/s^2" in record.getMessage()


def test_a_nan_sample_is_refused_with_its_position(tmp_path, graph_sensors):
    from engine.graph.inputs import load_take

    take = corpus.take_arrays()
    acc = take["acc_g"].copy()
    acc[120, 2, 1] = np.nan  # 120 Hz sample 120 = graph sample 30
    np.savez(tmp_path / "nan.npz", acc_g=acc, fps=take["fps"])
    with pytest.raises(MalformedFileError, match=r"nan\.npz: acc_g holds 1 non-finite sample\(s\) \(first at sample "
                                                 r"120 = 1\.000 s, sensor column 2\)"):
        load_take(tmp_path / "nan.npz", graph_sensors, 30.0)


def test_longest_path_of_a_graph():
    from engine.graph.input_checks import longest_path_samples

    chain = np.arange(4)
    assert longest_path_samples(chain, chain + 1, 5) == 5  # 0->1->2->3->4
    assert longest_path_samples(np.array([0, 0, 2, 3]), np.array([1, 2, 3, 4]), 5) == 4
    assert longest_path_samples(np.array([0, 1, 2]), np.array([1, 2, 0]), 4) == float("inf")  # a cycle
    assert longest_path_samples(np.array([1]), np.array([1]), 2) == float("inf")  # a self loop
