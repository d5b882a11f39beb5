"""Per-frame confidence and lost-track re-anchoring of the online decoder (engine/graph/confidence.py)."""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.config import GraphConfig
from engine.graph.confidence import CostHistory, CostWindow, confidence, reference_cost_per_sample
from engine.graph.graph import build_from_clips
from engine.graph.parts import EDGE_TRANSITION
from engine.graph.online import FixedLagSynthesizer
from engine.graph.viterbi import SearchWeights
from engine.mocap import SensorErrorModel

from .synth import gait_clip, observe, rigid_copy, walk_path

CFG = GraphConfig(window_frames=5, transition_threshold_m=0.05, min_jump_frames=8, connect=True,
                  connect_thresholds_m=[])


@pytest.fixture(scope="module")
def graph_and_path():
    a = gait_clip("a", n_frames=90, turn_rate=0.01, seed=1)
    b = rigid_copy(a, "b", angle_rad=0.4, shift_xz=(3.0, 1.0))
    c = rigid_copy(a, "c", angle_rad=-0.9, shift_xz=(-2.0, 4.0), seed=5)
    g = build_from_clips([a, b, c], CFG)
    nodes, edges = walk_path(g, 3, 240, np.random.default_rng(2), prefer_kind=EDGE_TRANSITION)
    return g, observe(g, nodes, edges, (0.0, 0.0), 0.0)


def test_confidence_formula_and_cost_window():
    assert confidence(1.0, 2.0) == 1.0 and confidence(4.0, 2.0) == pytest.approx(np.exp(-1.0))
    assert confidence(float("nan"), 1.0) == 1.0
    w = CostWindow(2)
    assert np.isnan(w.push(10.0))
    assert w.push(13.0) == 3.0 and w.push(14.0) == 2.0 and w.push(20.0) == pytest.approx(3.5)  # (20 - 13) / 2


def test_cost_history_centres_the_window_on_the_decided_sample():
    """Totals t^2: the window [s - 2, s + 2] costs ((s + 2)^2 - (s - 2)^2) / 4 = 2 s; cut at the newest sample
    it ends there; forgotten totals are ones no later window needs."""
    h = CostHistory(4)
    for t in range(10):
        h.push(float(t * t))
    assert h.per_sample_around(5) == 10.0
    assert h.per_sample_around(8) == (81 - 25) / 4  # newest is 9: the window [5, 9]
    assert h.per_sample_around(1) == (9 - 0) / 3  # from the first sample: [0, 3]
    h.drop_before(7)
    assert h.first == 3 and h.per_sample_around(7) == (81 - 25) / 4
    single = CostHistory(4)
    single.push(1.0)
    assert np.isnan(single.per_sample_around(0))


def test_confidence_of_a_decided_frame_sees_the_samples_after_it(graph_and_path):
    """With a lag, the frame where the sensors stop matching the database loses confidence from half a window
    *before* the change (the window centred on it sees the change), not only after."""
    g, (acc, _, _) = graph_and_path
    lost = acc.copy()
    lost[120:] = np.random.default_rng(4).normal(0, 3.0, lost[120:].shape)
    w = SearchWeights(0.5, 0, 0)
    syn = FixedLagSynthesizer(g, 2.0, w, confidence_reference=0.05, confidence_window_s=1.0, reanchor_ratio=0)
    conf = np.array([p.confidence for t in range(len(acc)) for p in syn.push(lost[t])] +
                    [p.confidence for p in syn.flush()])
    assert conf[100] > 0.9 and conf[112] < conf[100] / 2  # 8 samples before the change: 7 lost samples in view
    trailing = FixedLagSynthesizer(g, 0.0, w, confidence_reference=0.05, confidence_window_s=1.0, reanchor_ratio=0)
    conf0 = np.array([p.confidence for t in range(len(acc)) for p in trailing.push(lost[t])])
    assert conf0[112] > 0.9  # the window behind it (lag 0) has not seen the change yet


def test_reference_cost_grows_with_the_sensor_noise(graph_and_path):
    """Each left-out clip's readings are its own (the copies read other random accelerations), so even clean
    readings cost something; sensor noise adds to it."""
    g, _ = graph_and_path
    w = SearchWeights(0.5, 0, 0)
    clean = reference_cost_per_sample(g, w, error_model=SensorErrorModel(saturation_g=None))
    noisy = reference_cost_per_sample(g, w, error_model=SensorErrorModel(noise_g=1.0, saturation_g=None))
    assert 0 < clean < noisy


def test_confidence_high_on_database_motion_low_and_reanchors_when_lost(graph_and_path):
    g, (acc, ground, heading) = graph_and_path
    rng = np.random.default_rng(4)
    noisy = acc + rng.normal(0, 0.5, acc.shape)
    lost = noisy.copy()
    lost[120:] = rng.normal(0, 3.0, lost[120:].shape)  # from sample 120 the sensors read nothing the graph holds
    w = SearchWeights(0.5, 0, 0)
    ref = reference_cost_per_sample(g, w, error_model=SensorErrorModel(noise_g=0.5, saturation_g=None))
    syn = FixedLagSynthesizer(g, 0.5, w, confidence_reference=ref, reanchor_after_s=1.0)
    poses = [p for t in range(len(acc)) for p in syn.push(lost[t])] + syn.flush()
    conf = np.array([p.confidence for p in poses])
    assert len(poses) == len(acc) and np.all((conf > 0) & (conf <= 1))
    assert np.median(conf[20:110]) > 0.9
    assert np.median(conf[160:]) < 0.05
    assert syn.reanchors and all(t >= 120 + 30 for t in syn.reanchors)  # only once lost for the full second
    calm = FixedLagSynthesizer(g, 0.5, w, confidence_reference=ref, reanchor_after_s=1.0)
    for t in range(len(acc)):
        calm.push(noisy[t])
    assert calm.reanchors == []
