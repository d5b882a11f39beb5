"""The maintained DTW libraries (engine extra) give the hand-written recursions' answers on the project's own
inputs: dtaidistance for the HMM (distances and registration paths), dtw-python for the interpolation DTW."""
from __future__ import annotations

import numpy as np
import pytest

from engine.graph.interpolate import slope_constrained_dtw
from engine.graph.slope_dtw import HAVE_DTW_PYTHON, library_path
from engine.hmm.dtw import HAVE_DTAIDISTANCE, distance_matrix, dtw, dtw_reference

from bench.support.dtw_inputs import hmm_inputs, interpolation_costs


@pytest.mark.skipif(not HAVE_DTAIDISTANCE, reason="dtaidistance (engine extra) not installed")
def test_dtaidistance_matches_the_reference_on_hmm_segments():
    groups, pairs = hmm_inputs()
    assert len(groups) >= 4 and len(pairs) >= 20
    for seqs in groups:
        ref = np.array([[dtw_reference(a, b)[0] if i != j else 0.0 for j, b in enumerate(seqs)]
                        for i, a in enumerate(seqs)])
        np.testing.assert_allclose(distance_matrix(seqs), ref, rtol=1e-12, atol=1e-9)
    for a, b in pairs:
        d_lib, p_lib = dtw(a, b)
        d_ref, p_ref = dtw_reference(a, b)
        assert d_lib == pytest.approx(d_ref, rel=1e-12)
        np.testing.assert_array_equal(p_lib, p_ref)


@pytest.mark.skipif(not HAVE_DTW_PYTHON, reason="dtw-python (engine extra) not installed")
def test_dtw_python_matches_the_reference_on_sample_graph_costs():
    costs = interpolation_costs()
    assert len(costs) >= 10
    for cost in costs:
        ref, lib = slope_constrained_dtw(cost), library_path(cost)
        assert (ref is None) == (lib is None)
        if ref is not None:
            np.testing.assert_array_equal(lib[0], ref[0])
            np.testing.assert_array_equal(lib[1], ref[1])


def test_unconnected_corners_give_none_both_ways():
    cost = np.ones((6, 6))
    cost[2:4, :] = np.inf
    assert slope_constrained_dtw(cost) is None
    if HAVE_DTW_PYTHON:
        assert library_path(cost) is None
