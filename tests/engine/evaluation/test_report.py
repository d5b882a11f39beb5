"""Graph report and coverage warning on tiny graphs with exact answers."""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.config import GraphConfig
from engine.graph.graph import MotionGraph, build_from_clips
from engine.graph.parts import EDGE_NATURAL, EDGE_SLOWDOWN, EDGE_TRANSITION, NODE_ORIGINAL, NODE_SLOW
from engine.graph.report import coverage_warning, format_report, graph_report, motion_range
from tests.engine.graph.synth import gait_clip


def hand_graph() -> MotionGraph:
    """Clips A (nodes 0-3), B (4-6), C (7-8), D (10-11) and a slow-down node 9 between A's frames 0 and 1.

    A loops (3 -> 0), A <-> B (2 -> 4, 6 -> 1): one component {0..6, 9}. C is entered from B (5 -> 7) and ends
    in a dead end (8). D leads into A (11 -> 0) but nothing leads into D."""
    clip = np.array([0, 0, 0, 0, 1, 1, 1, 2, 2, 0, 3, 3])
    frame = np.array([0, 1, 2, 3, 0, 1, 2, 0, 1, 0.5, 0, 1], np.float32)
    kind = np.full(12, NODE_ORIGINAL, np.int8)
    kind[9] = NODE_SLOW
    edges = [(0, 1, EDGE_NATURAL), (1, 2, EDGE_NATURAL), (2, 3, EDGE_NATURAL), (3, 0, EDGE_TRANSITION),
             (2, 4, EDGE_TRANSITION), (4, 5, EDGE_NATURAL), (5, 6, EDGE_NATURAL), (6, 1, EDGE_TRANSITION),
             (5, 7, EDGE_TRANSITION), (7, 8, EDGE_NATURAL), (0, 9, EDGE_SLOWDOWN), (9, 1, EDGE_SLOWDOWN),
             (10, 11, EDGE_NATURAL), (11, 0, EDGE_TRANSITION)]
    edges.sort(key=lambda e: (e[1], e[0]))
    src, dst, ekind = (np.array(v) for v in zip(*edges))
    n = 12
    return MotionGraph(
        config=GraphConfig(), clip_names=["A", "B", "C", "D"], label_names=["x"],
        node_clip=clip.astype(np.int32), node_clip2=np.full(n, -1, np.int32), node_frame=frame, node_kind=kind,
        node_label=np.zeros(n, np.int16), node_positions_m=np.zeros((n, 3, 3), np.float32),
        node_heading_rad=np.zeros(n), node_ground_m=np.zeros((n, 2)), node_contacts=np.zeros((n, 2), bool),
        node_arrival=np.zeros(n, np.int32), edge_src=src.astype(np.int32), edge_dst=dst.astype(np.int32),
        edge_kind=ekind.astype(np.int8), edge_meta=np.zeros(len(src), np.int32),
        meta_acc_g=np.zeros((1, 1, 3), np.float32), meta_dheading_rad=np.zeros(1), meta_dpos_m=np.zeros((1, 2)))


def test_component_report_has_the_exact_numbers():
    g = hand_graph()
    assert g.inconsistency() is None
    r = graph_report(g)
    assert (r.nodes, r.edges, r.frames, r.clips) == (12, 14, 11, 4)
    assert r.components == 5  # {0..6, 9}, {7}, {8}, {10}, {11}
    assert (r.largest_nodes, r.largest_frames) == (8, 7)
    assert r.largest_node_share == pytest.approx(8 / 12) and r.largest_frame_share == pytest.approx(7 / 11)
    assert r.dead_ends == 1  # node 8
    assert r.cannot_reach_largest == 2  # nodes 7, 8
    assert (r.clips_in_largest, r.clips_reachable) == (2, 3)  # A, B; A, B, C (not D)
    text = format_report(r)
    assert "5" in text and "66.7 %" in text and "63.6 %" in text


def motion_graph(msv: bool = False) -> MotionGraph:
    """A straight walk at 0.04 m/frame (1.2 m/s) and a turning walk at 0.01 rad/frame (17.19 deg/s)."""
    clips = [gait_clip("straight", 120, speed=0.04), gait_clip("turn", 120, turn_rate=0.01, speed=0.02, seed=1)]
    return build_from_clips(clips, GraphConfig(msv=msv))


def test_turn_rates_and_speeds_covered_are_exact():
    m = motion_range(motion_graph())
    assert m.speedup == 1.0
    assert m.max_turn_deg_s == pytest.approx(np.degrees(0.01 * 30))
    assert m.max_speed_mps == pytest.approx(0.04 * 30)
    assert m.turn_deg_s[-1] == pytest.approx(np.degrees(0.3)) and m.speed_mps[-1] == pytest.approx(1.2)
    assert motion_range(motion_graph(msv=True)).max_turn_deg_s == pytest.approx(2 * np.degrees(0.3))


def camera_track(turn_deg_s: float, speed_mps: float, seconds: float = 20.0, fps: float = 30.0, seed: int = 0):
    """A walk at constant speed and turn rate seen by a camera with 5 cm / 10 deg noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * fps)) / fps
    heading = np.radians(turn_deg_s) * t
    step = np.stack([np.sin(heading), np.cos(heading)], axis=1) * speed_mps / fps
    ground = np.cumsum(step, axis=0) + rng.normal(0, 0.05, step.shape)
    return ground, heading + rng.normal(0, np.radians(10), len(t))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_coverage_warning_fires_on_a_fast_turn_and_not_on_a_slow_one(seed):
    m = motion_range(motion_graph())  # covers 17.2 deg/s, 1.2 m/s
    slow = coverage_warning(m, *camera_track(10.0, 1.0, seed=seed), 30.0)
    assert slow is None
    fast = coverage_warning(m, *camera_track(60.0, 1.0, seed=seed), 30.0)
    assert fast is not None and "turns at" in fast and "moves at" not in fast and "\n" not in fast
    running = coverage_warning(m, *camera_track(5.0, 3.0, seed=seed), 30.0)
    assert running is not None and "moves at" in running and "turns at" not in running


def test_coverage_tolerates_camera_gaps():
    m = motion_range(motion_graph())
    pos, head = camera_track(60.0, 1.0)
    pos[::3], head[::3] = np.nan, np.nan  # a camera at two thirds of the graph rate
    assert "turns at" in coverage_warning(m, pos, head, 30.0)
    assert coverage_warning(m, None, None, 30.0) is None
