"""Motion-graph synthesis from sparse accelerometers + global position (seed 000, Kelly et al.).

Offline: `MotionGraph.build(motions, placements, config)` (or `build_from_clips` on plain arrays) makes a graph
whose nodes are database poses at 30 Hz and whose edges carry heading/position offsets and virtual
accelerations; `.save(path)` / `MotionGraph.load(path)`.
Online: `ViterbiSearch(graph, weights).run(Observations(...), constraints)` for a whole take, or
`FixedLagSynthesizer(graph, lag_s).push(acc_g, pos_m, heading_rad)` sample by sample; `path_to_motion` turns a
result into a blended, foot-skate-cleaned engine.mocap Motion for `write_bvh`.
"""
from .clips import ClipData
from .config import GraphConfig
from .graph import MotionGraph, build_from_clips
from .online import EmittedPose, FixedLagSynthesizer
from .poses import world_joint_positions
from .postprocess import path_to_motion
from .viterbi import Constraint, Observations, SearchResult, SearchWeights, ViterbiLattice
from .search import ViterbiSearch


def label_constraint(graph: MotionGraph, label: str, frame: int, tolerance_frames: int = 10) -> Constraint:
    """Seed 000 section 5.4 requirement: be on a node of clips labelled `label` within +-tolerance of `frame`."""
    return Constraint(frame=frame, tolerance_frames=tolerance_frames, node_mask=graph.label_mask(label))


__all__ = [
    "ClipData", "Constraint", "EmittedPose", "FixedLagSynthesizer", "GraphConfig", "MotionGraph", "Observations",
    "SearchResult", "SearchWeights", "ViterbiLattice", "ViterbiSearch", "build_from_clips", "label_constraint",
    "path_to_motion", "world_joint_positions",
]
