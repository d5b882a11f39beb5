"""Known answers for the real-recording bench's reference records: the hold read perfectly is the perfect record
when the hold has no error of its own, so the bench's "floor" row measures the hold's error and nothing else."""
from __future__ import annotations

import numpy as np
import pytest

from bench.bench_real_recording import HOLD_S, NAMES, RATE_HZ, hold_floor_record, perfect_record, simulate_recording
from engine.evaluation.takes import chain_clips
from engine.mocap import load_sensor_calibration
from engine.mocap import quaternions as quat
from engine.mocap.orientation_calibration import pose_sensor_orientations


NO_FILTER_ERROR = {"tilt_noise_deg": 0.0, "yaw_walk_deg_per_sqrt_min": 0.0, "yaw_drift_deg_per_min": 0.0}


def _records(motions, tmp_path, orientation_filter: str, posing_error_deg: float, changes: dict):
    take = chain_clips(motions, [0], [m.name for m in motions])
    rec = simulate_recording(take, "apose:60", "random", orientation_filter, np.random.default_rng(3),
                             posing_error_deg, filter_changes=changes)
    hold_floor_record(tmp_path / "floor.json", rec, take.skeleton, "apose:60", orientation_filter)
    perfect_record(tmp_path / "perfect.json", rec, take.skeleton)
    floor, perfect = (load_sensor_calibration(tmp_path / f"{name}.json").orientation_calibration(NAMES)
                      for name in ("floor", "perfect"))
    return rec, floor, perfect


def _angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.linalg.norm(quat.to_rotvec(quat.multiply(a, quat.conjugate(b))), axis=-1))


@pytest.mark.parametrize("orientation_filter, changes", [("9axis", {"north_spread_deg": 0.0}), ("6axis", {})])
def test_a_flawless_hold_reads_as_the_perfect_record(motions, tmp_path, orientation_filter, changes):
    rec, floor, perfect = _records(motions, tmp_path, orientation_filter, 0.0, {**NO_FILTER_ERROR, **changes})
    assert np.allclose(_angles_deg(floor.mount_wxyz, perfect.mount_wxyz), 0.0, atol=1e-4)
    assert np.allclose(np.angle(np.exp(1j * (floor.yaw_rad - perfect.yaw_rad))), 0.0, atol=1e-6)
    if orientation_filter == "6axis":  # each sensor its own north: the floor is given each
        assert np.ptp(perfect.yaw_rad) > 0.1


def test_the_floor_keeps_the_athletes_posing_error(motions, tmp_path):
    """A 9-axis filter with no error of its own, the athlete 5 deg (sd) off the template on every segment: the
    floor record reads the hold as the template exactly, so each strap is off the true one by the turn that
    segment was off the template (what the perfect record sees in the hold), and every yaw is the one north."""
    rec, floor, perfect = _records(motions, tmp_path, "9axis", 5.0, {**NO_FILTER_ERROR, "north_spread_deg": 0.0})
    held = rec.quat_device[:int(round(HOLD_S * RATE_HZ))]
    template = pose_sensor_orientations(rec.take.skeleton, NAMES, "apose", float(rec.take.heading_rad[0]), 60.0)
    assert np.allclose(_angles_deg(floor.world(held), template[None]), 0.0, atol=1e-4)
    posing = _angles_deg(perfect.world(held[0]), template)
    assert np.all(posing > 0.1)
    assert np.allclose(_angles_deg(floor.mount_wxyz, perfect.mount_wxyz), posing, atol=1e-4)
    assert np.allclose(floor.yaw_rad, floor.yaw_rad[0])
