"""The builder's live-rate check (engine/graph/budget.py)."""
from __future__ import annotations

from engine.graph.budget import live_verdict, online_rate
from engine.graph.config import GraphConfig
from engine.graph.graph import build_from_clips

from .synth import gait_clip, rigid_copy


def test_online_rate_is_measured_and_the_verdict_says_why_not():
    a = gait_clip("a", n_frames=60, seed=1)
    g = build_from_clips([a, rigid_copy(a, "b", 0.5, (1.0, 2.0))], GraphConfig(window_frames=5))
    cpu, wall = online_rate(g, n_samples=20)
    assert cpu > 0 and wall > 0
    assert live_verdict(g, 100.0, 100.0) is None
    assert "below the 30/s" in live_verdict(g, 10.0, 10.0) and f"{g.n_edges} edges" in live_verdict(g, 10.0, 10.0)
    assert "other processes share the cores" in live_verdict(g, 100.0, 10.0)
