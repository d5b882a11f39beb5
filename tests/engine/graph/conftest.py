"""Real-mocap fixtures: the CMU subject-16 clips shipped in engine/data (always present)."""
from __future__ import annotations

import pytest

from engine.graph.config import GraphConfig
from engine.graph.graph import build_from_clips
from engine.graph.mocap_adapter import clips_from_motions
from engine.mocap import load_database, sample_clips, standard_placements


@pytest.fixture(scope="session")
def sample_motions():
    paths = [p for name, p in sample_clips().items() if name.startswith("16_")]
    assert len(paths) >= 5, "the shipped CMU subject-16 sample is missing from engine/data"
    return load_database(paths, fps=30.0)


@pytest.fixture(scope="session")
def sample_clipdata(sample_motions):
    cfg = GraphConfig(msv=True)
    placements = standard_placements(sample_motions[0].skeleton)
    return clips_from_motions(sample_motions, placements, cfg), cfg


@pytest.fixture(scope="session")
def sample_graph(sample_clipdata):
    clips, cfg = sample_clipdata
    return build_from_clips(clips, GraphConfig(msv=False))


@pytest.fixture(scope="session")
def sample_graph_msv(sample_clipdata):
    clips, cfg = sample_clipdata
    return build_from_clips(clips, cfg)
