"""Shared virtual recordings for the import tests (the shipped CMU walk 16_11 at 100 Hz, seven sensors)."""
from __future__ import annotations

import pytest

from engine.mocap import SEED000_SENSORS, standard_placements

from bench.support.imu_formats import Truth, clip, virtual_recording


@pytest.fixture(scope="session")
def walk_truth() -> Truth:
    motion = clip("16_11", 100.0)
    return virtual_recording(motion, standard_placements(motion.skeleton, list(SEED000_SENSORS) + ["right_foot"]))
