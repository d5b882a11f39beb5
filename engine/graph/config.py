"""Build-time configuration of a motion graph (saved beside the arrays as JSON so a graph documents itself)."""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field


@dataclass
class GraphConfig:
    """Choices the paper leaves open, with the defaults we measured to work (docs/engine-graph.md).

    transition_threshold_m: RMS point-cloud distance (m) below which two contact-change frames may be joined.
    window_frames: frames in the point-cloud window (Kovar uses ~1/3 s).
    joint_weights: per-joint weights of the point cloud (None = equal weights).
    min_jump_frames: a transition inside one clip must jump at least this far (shorter jumps are near-duplicates
        of the natural edge and only slow the search).
    max_transitions_per_frame: keep only this many closest transitions leaving one frame (0 = no cap).
    msv / interp: add motion speed variations / interpolated motions (seed 000 sections 4.1 / 4.2).
    interp_threshold_m, interp_min_length_s: the similarity threshold t_i and the minimum blended length.
    interp_max_share: interpolated poses capped at this share of the database's frames, cleanest alignments
        first (None = no cap; the paper added 1.15x on 15k frames, Bandai dataset 2 would add 47x uncapped).
    connect: make the graph one strongly connected component (engine/graph/components.py): candidates every
        `idle_spacing_frames` inside long single-contact-state runs, transitions at the relaxed
        `connect_thresholds_m` (tried in turn) for frames outside the largest component until it holds
        `min_component_share` of the frames (at most `connect_max_per_frame` relaxed transitions leave one
        frame), then everything outside it pruned. Off in the library (exact-answer
        tests build small graphs with dead ends on purpose); `courtside build-graph` turns it on.
    """

    fps: float = 30.0
    window_frames: int = 9
    transition_threshold_m: float = 0.06
    joint_weights: list[float] | None = None
    min_jump_frames: int = 8
    max_transitions_per_frame: int = 10
    msv: bool = False
    interp: bool = False
    interp_threshold_m: float = 0.05
    interp_min_length_s: float = 0.5
    interp_max_share: float | None = 0.5
    sensor_names: list[str] = field(default_factory=list)
    connect: bool = False
    idle_spacing_frames: int = 15
    connect_thresholds_m: list[float] = field(default_factory=lambda: [0.09, 0.12, 0.18, 0.25])
    min_component_share: float = 0.9
    connect_max_per_frame: int = 2

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)
