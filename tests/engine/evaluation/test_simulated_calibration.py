"""evaluate's issue-29 capture (simulate.take_calibrated_sensors): straps uniform over all rotations, an A-pose
start of an arm angle the calibration is not told, solved from the take by `courtside calibrate`'s code."""
from __future__ import annotations

import numpy as np
import pytest

from engine.errors import CourtsideError
from engine.evaluation.cli import main as evaluate_main
from engine.evaluation.simulate import CalibrationCapture, accelerometers, take_calibrated_sensors
from engine.evaluation.takes import chain_clips
from engine.graph.config import GraphConfig
from engine.graph.graph import build_from_clips
from engine.graph.mocap_adapter import clips_from_motions
from engine.mocap import SEED000_SENSORS, standard_placements
from engine.mocap import quaternions as quat
from engine.mocap.orientation import OrientationErrorModel, virtual_orientations

NAMES = list(SEED000_SENSORS)


@pytest.fixture(scope="module")
def graph(motions):
    cfg = GraphConfig(msv=False, sensor_names=NAMES)
    graph = build_from_clips(clips_from_motions(motions, standard_placements(motions[0].skeleton, NAMES), cfg), cfg)
    graph.skeleton = motions[0].skeleton
    return graph


def test_random_straps_and_an_a_pose_start_are_solved_from_the_take(motions, graph):
    """The database holds the take's clips (the method's known answer): the accelerations come back in the nominal
    frames and the calibrated limb orientations are the true ones, whatever the straps (uniform over all
    rotations), within 3 deg."""
    take = chain_clips(motions, [1, 3, 5], [m.name for m in motions])
    acc, _ = accelerometers(take, NAMES, None, np.random.default_rng(0))
    capture = CalibrationCapture(posing_error_deg=0.0, strapping="random", start_pose="apose:40")
    got_acc, readings, cal = take_calibrated_sensors(take, NAMES, acc, OrientationErrorModel(yaw_offset=True),
                                                     np.random.default_rng(1), capture, graph)
    assert readings.shape == (take.n_frames, len(NAMES), 4)
    limbs = [k for k, n in enumerate(NAMES) if n not in ("lower_back", "chest")]
    still = np.linalg.norm(acc, axis=-1) < 1.5  # the direction of a strong acceleration shows the strap best
    cos = np.sum(got_acc * acc, axis=-1) / np.linalg.norm(got_acc, axis=-1) / np.linalg.norm(acc, axis=-1)
    assert np.degrees(np.arccos(np.clip(cos[:, limbs][still[:, limbs]], -1, 1))).max() < 3.0
    truth = np.concatenate([virtual_orientations(s.motion, standard_placements(s.motion.skeleton, NAMES))
                            for s in take.segments])
    world = cal.world(readings)  # the limbs' orientations relative to one another are the true ones
    rel = quat.multiply(quat.conjugate(world[:, limbs[:1]]), world[:, limbs])
    rel_true = quat.multiply(quat.conjugate(truth[:, limbs[:1]]), truth[:, limbs])
    angle = np.degrees(2 * np.arccos(np.clip(np.abs(np.sum(rel * rel_true, axis=-1)), 0, 1)))
    assert np.median(angle) < 3.0


def test_bad_start_pose_option_is_one_line(capsys):
    with pytest.raises(CourtsideError, match="--start-pose"):
        evaluate_main(["--protocol", "loco", "--sample", "--inputs", "acc+ori", "--start-pose", "apose@0:2"])


@pytest.mark.parametrize("north", ["shared", "own"])
def test_the_capture_tells_the_solve_the_north(motions, graph, north):
    """`evaluate --north` reaches the solve as `calibrate --north` would: told one north, every sensor gets the one
    heading (equal yaws) although each filter has its own; told its own, each gets its own (tens of degrees
    apart, as the filters' norths are)."""
    take = chain_clips(motions, [1, 3, 5], [m.name for m in motions])
    acc, _ = accelerometers(take, NAMES, None, np.random.default_rng(0))
    capture = CalibrationCapture(posing_error_deg=0.0, strapping="random", start_pose="apose:40", north=north)
    *_, cal = take_calibrated_sensors(take, NAMES, acc, OrientationErrorModel(yaw_offset=True),
                                      np.random.default_rng(1), capture, graph)
    spread_deg = np.degrees(np.ptp(np.unwrap(cal.yaw_rad)))
    assert (spread_deg < 1e-6) if north == "shared" else (spread_deg > 10.0)
