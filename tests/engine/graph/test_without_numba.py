"""Without the `engine` extra (no numba), the motion-graph search falls back to the numpy reference kernel,
refuses an explicit request for numba with the install hint, and still finds a database clip from its own
virtual sensors."""
from __future__ import annotations

import subprocess
import sys

CODE = """
import sys
sys.modules["numba"] = None          # `import numba` now raises ImportError, as on a core-only install
import numpy as np
import engine.graph.viterbi as viterbi
from engine.graph import GraphConfig, MotionGraph, Observations, ViterbiSearch
from engine.mocap import load_database, sample_clips, standard_placements, virtual_accelerometers

assert viterbi.kernels_numba is None and viterbi.DEFAULT_KERNEL == "numpy"
motions = load_database([sample_clips()["16_11"], sample_clips()["16_35"]], fps=30.0)
placements = standard_placements(motions[0].skeleton)
graph = MotionGraph.build(motions, placements, GraphConfig())
obs = Observations(virtual_accelerometers(motions[0], placements)[5:65], None, None)
try:
    ViterbiSearch(graph, kernel="numba").run(obs)
    raise SystemExit("asking for numba without numba must be refused")
except ValueError as exc:
    assert "courtside[engine]" in str(exc), exc
res = ViterbiSearch(graph).run(obs)
share = float(np.mean(graph.node_clip[res.nodes] == 0))
print(f"share {share:.3f}")
"""


def test_graph_defaults_to_numpy_and_refuses_numba_without_numba():
    out = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    share = float(out.stdout.split()[-1])
    assert share >= 0.9, f"only {share:.0%} of the synthesised frames come from the clip whose sensors were replayed"
