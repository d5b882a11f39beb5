"""Motion-graph synthesis from sparse accelerometers + global position (seed 000, Kelly et al.).

Offline: `MotionGraph.build(motions, placements, config)` (or `build_from_clips` on plain arrays) makes a graph
whose nodes are database poses at 30 Hz and whose edges carry heading/position offsets and virtual
accelerations; `.save(path)` / `MotionGraph.load(path)`.
Online: `ViterbiSearch(graph, weights).run(Observations(...), constraints)` for a whole take, or
`FixedLagSynthesizer(graph, lag_s).push(acc_g, pos_m, heading_rad)` sample by sample, each emitted pose a decided
pose (root + local rotations, joints their forward kinematics: engine.graph.decided), which
`engine.stream.decided.poses_to_motion` turns into the engine.mocap Motion `write_bvh` writes.
"""
from .clips import ClipData
from .config import GraphConfig
from .graph import MotionGraph, build_from_clips
from .online import EmittedPose, FixedLagSynthesizer
from .poses import world_joint_positions
from .viterbi import Constraint, Observations, SearchResult, SearchWeights, ViterbiLattice
from .search import ViterbiSearch


def label_constraint(graph: MotionGraph, label: str, frame: int, tolerance_frames: int = 10) -> Constraint:
    """Seed 000 section 5.4 requirement: be on a node of clips labelled `label` within +-tolerance of `frame`."""
    return Constraint(frame=frame, tolerance_frames=tolerance_frames, node_mask=graph.label_mask(label))


__all__ = [
    "ClipData", "Constraint", "EmittedPose", "FixedLagSynthesizer", "GraphConfig", "MotionGraph", "Observations",
    "SearchResult", "SearchWeights", "ViterbiLattice", "ViterbiSearch", "build_from_clips", "label_constraint",
    "world_joint_positions",
]
