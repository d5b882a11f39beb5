"""The CMU subject-16 clips shipped in engine/data (always present) at the graph rate."""
from __future__ import annotations

import pytest

from engine.mocap import load_database, sample_clips


@pytest.fixture(scope="session")
def motions():
    paths = [p for name, p in sample_clips().items() if name.startswith("16_")]
    return load_database(paths, fps=30.0)
