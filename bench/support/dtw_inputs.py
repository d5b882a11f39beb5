"""The project's own DTW inputs, captured while the engine builds: the HMM's phase segments (medoid candidates and
the (segment, reference) pairs it registers) and the interpolation cost matrices of the sample graph."""
from __future__ import annotations

from unittest import mock

import numpy as np

from engine.mocap import load_database, sample_clips


def sample_motions(fps: float = 30.0):
    return load_database([p for n, p in sorted(sample_clips().items()) if n.startswith("16_")], fps=fps)


def hmm_inputs() -> tuple[list[list[np.ndarray]], list[tuple[np.ndarray, np.ndarray]]]:
    """(medoid candidate lists, registered (segment, reference) pairs) of HMM training on the shipped walks."""
    import engine.hmm.model as model
    from engine.hmm.evaluation import train_model

    groups, pairs = [], []
    real_medoid, real_dtw = model.medoid, model.dtw

    def medoid(seqs):
        groups.append([np.array(s) for s in seqs])
        return real_medoid(seqs)

    def dtw(a, b):
        pairs.append((np.array(a), np.array(b)))
        return real_dtw(a, b)

    with mock.patch.object(model, "medoid", medoid), mock.patch.object(model, "dtw", dtw):
        train_model(sample_motions())
    return groups, pairs


def interpolation_costs() -> list[np.ndarray]:
    """Every cost matrix the interpolation DTW sees while the sample graph is built with --interp."""
    import engine.graph.interpolate as interpolate
    from engine.graph.config import GraphConfig
    from engine.graph.graph import build_from_clips
    from engine.graph.mocap_adapter import clips_from_motions, mocap_sensor_model
    from engine.mocap import SEED000_SENSORS, standard_placements

    costs: list[np.ndarray] = []

    def capture(cost):
        costs.append(np.array(cost))
        return interpolate.slope_constrained_dtw(cost)

    config = GraphConfig(interp=True, sensor_names=list(SEED000_SENSORS))
    motions = sample_motions(config.fps)
    placements = standard_placements(motions[0].skeleton, SEED000_SENSORS)
    clips = clips_from_motions(motions, placements, config, [m.name for m in motions])
    with mock.patch.object(interpolate, "library_path", capture), mock.patch.object(interpolate, "HAVE_DTW_PYTHON", True):
        build_from_clips(clips, config, mocap_sensor_model(motions[0].skeleton, placements, config.fps))
    return costs
