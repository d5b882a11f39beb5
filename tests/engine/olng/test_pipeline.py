"""End-to-end OLNG reconstruction on procedural motion with a held-out tempo (spec A5.7)."""
from __future__ import annotations

import numpy as np
import pytest

from engine.olng import EnergyConfig, NeighbourhoodGraphConfig, KnowledgeBase, OLNGConfig, OLNGReconstructor

from .synthetic import RIG, SENSORS, make_clip, root_frame_positions

GRAPH = NeighbourhoodGraphConfig(k_neighbours=256, i_best=64, window=16)


@pytest.fixture(scope="module")
def knowledge_base() -> KnowledgeBase:
    clips = [make_clip("walk", s, 8) for s in (0.7, 1.0, 1.3, 1.6)] + [make_clip("jacks", s, 8) for s in (0.8, 1.2)]
    return KnowledgeBase.from_clips(RIG, SENSORS, clips, fps=25.0)


def _rms_cm(kb, clip, config=OLNGConfig(graph=GRAPH)):
    rec = OLNGReconstructor(kb, config)
    out = [rec.push(a) for a in clip.acc_g]
    pred = np.array([o.joints_root_m for o in out])
    truth = root_frame_positions(clip)
    return float(np.sqrt(((pred - truth) ** 2).sum(-1).mean(-1)).mean() * 100), out


def test_held_out_tempo_beats_mean_pose_and_mahalanobis_prior(knowledge_base):
    clip = make_clip("walk", 0.85, 4)
    truth = root_frame_positions(clip)
    mean_pose_cm = np.sqrt(((knowledge_base.x_m.mean(0) - truth) ** 2).sum(-1).mean(-1)).mean() * 100
    kernel_cm, _ = _rms_cm(knowledge_base, clip)
    maha_cm, _ = _rms_cm(knowledge_base, clip, OLNGConfig(graph=GRAPH, energy=EnergyConfig(kernel="mahalanobis")))
    assert kernel_cm < 0.5 * mean_pose_cm
    assert kernel_cm < 0.8 * maha_cm     # Fig. 11: the kernel prior beats the Gaussian/Mahalanobis prior


def test_time_warping_beats_linear_search_at_varying_tempo(knowledge_base):
    """Fig. 13(b): jumping jacks at a smoothly varying tempo (0.6x-1.4x) against a database holding two fixed
    tempi; M = 32 (the default window) so a linear search must match whole 1.3 s stretches at one tempo."""
    clip = make_clip("jacks", 1.0, 6, speed_profile=lambda t: 1.0 + 0.4 * np.sin(2 * np.pi * t / 6))
    warp = NeighbourhoodGraphConfig(k_neighbours=256, i_best=64, window=32)
    linear = NeighbourhoodGraphConfig(k_neighbours=256, i_best=64, window=32, max_column_step=1, max_warp=1)
    warp_cm, _ = _rms_cm(knowledge_base, clip, OLNGConfig(graph=warp))
    linear_cm, _ = _rms_cm(knowledge_base, clip, OLNGConfig(graph=linear))
    assert warp_cm < 0.8 * linear_cm


def test_streaming_output_from_first_frame_with_plausible_root_motion(knowledge_base):
    clip = make_clip("walk", 1.0, 3)
    rec = OLNGReconstructor(knowledge_base, OLNGConfig(graph=GRAPH))
    rec.reset_root(clip.root_pos_m[0], 0.0)
    first = rec.push(clip.acc_g[0])
    assert first.joints_root_m.shape == (len(RIG.names), 3) and np.all(np.isfinite(first.joints_world_m))
    out = [first] + [rec.push(a) for a in clip.acc_g[1:]]
    travelled = out[-1].root_pos_m - out[0].root_pos_m
    true_travel = clip.root_pos_m[-1] - clip.root_pos_m[0]
    assert travelled[2] == pytest.approx(true_travel[2], rel=0.2)
    assert abs(travelled[0]) < 0.1 * true_travel[2]
    np.testing.assert_allclose(np.linalg.norm(out[-1].local_quats, axis=-1), 1.0, atol=1e-9)
    assert rec.timings.frames == len(clip.acc_g)


def test_rejects_wrong_sensor_count(knowledge_base):
    rec = OLNGReconstructor(knowledge_base, OLNGConfig(graph=GRAPH))
    with pytest.raises(ValueError, match="4 sensors"):
        rec.push(np.zeros((3, 3)))


def test_knowledge_base_round_trips_through_npz(knowledge_base, tmp_path):
    path = tmp_path / "kb.npz"
    knowledge_base.save(path)
    loaded = KnowledgeBase.load(path)
    np.testing.assert_array_equal(loaded.alpha_g, knowledge_base.alpha_g)
    np.testing.assert_array_equal(loaded.clip_id, knowledge_base.clip_id)
    assert loaded.rig.names == knowledge_base.rig.names
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(Exception, match="bad.npz"):
        KnowledgeBase.load(tmp_path / "bad.npz")


def test_dropped_samples_hold_the_last_reading(knowledge_base):
    clip = make_clip("walk", 1.0, 3)
    acc = clip.acc_g.copy()
    acc[20:23, 1] = np.nan                      # the right-wrist sensor drops three frames
    rec = OLNGReconstructor(knowledge_base, OLNGConfig(graph=GRAPH))
    out = np.array([rec.push(a).joints_root_m for a in acc])
    assert np.all(np.isfinite(out)) and rec.dropped_readings == 3
    truth = root_frame_positions(clip)
    assert np.sqrt(((out[20:26] - truth[20:26]) ** 2).sum(-1).mean(-1)).mean() < 0.1   # m: stays on track
    with pytest.raises(ValueError, match="first reading"):
        OLNGReconstructor(knowledge_base, OLNGConfig(graph=GRAPH)).push(np.full((4, 3), np.nan))


def test_the_console_says_a_knowledge_base_keeps_its_mountings(knowledge_base, tmp_path):
    """A calibration record with a saved knowledge base: the OLNG's adapter declares that its database keeps the
    virtual sensors it was built with, so the console says the record's mountings do not reach it (a motion
    graph file takes them: `tests/gui/test_imported_playback.py`)."""
    from engine.stream.databases import engine_spec

    path = tmp_path / "kb.npz"
    knowledge_base.save(path)
    record = object()  # the OLNG's load_spec reads nothing of a record; any one must draw the note
    spec, notes = engine_spec("olng", kb_path=path, calibration=record)
    assert spec.name == "olng"
    assert [note for note in notes if "kb.npz: the database's virtual sensors keep the mounting" in note]
    assert engine_spec("olng", kb_path=path)[1] == []
