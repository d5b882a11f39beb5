"""Motion speed variations (seed 000 section 4.1, after Ren et al.).

Between consecutive frames f, f+1 of a clip a *slow-down node* holds the pose halfway between them, so the
path f -> s -> f+1 plays that stretch at half speed; a *speed-up edge* f -> f+2 skips a frame (double speed).
Alternating with normal edges gives intermediate speeds. Nothing is added where a foot-less (airborne) frame is
involved: a flight phase played at another speed would halve or double gravity. The accelerations of the
time-warped motion come from the clip's `acc_slow_g` / `acc_fast_g` streams (virtual sensors on the clip
resampled in time), so the sensors see the real half/double-speed dynamics, not scaled copies.
"""
from __future__ import annotations

import numpy as np

from engine.mocap import quaternions as quat

from .clips import ClipData
from .geometry import wrap_angle
from .parts import EDGE_SLOWDOWN, EDGE_SPEEDUP, NODE_SLOW, GraphParts
from .metadata import step_offsets


def add_speed_variations(parts: GraphParts, clips: list[ClipData], offsets: np.ndarray,
                         label_names: list[str]) -> None:
    """Append slow-down nodes with their two edges each, and speed-up edges, for every clip."""
    has_rot = "node_rotations" in parts.node
    for ci, clip in enumerate(clips):
        if clip.acc_slow_g is None or clip.acc_fast_g is None:
            raise ValueError(f"clip {clip.name!r}: MSV needs the half- and double-speed acceleration streams")
        grounded = clip.contacts.any(axis=1)
        f = np.flatnonzero(grounded[:-1] & grounded[1:])  # slow-down node between f and f+1
        base = offsets[ci]
        pos = 0.5 * (clip.positions_m[f] + clip.positions_m[f + 1])
        heading = clip.heading_rad[f] + 0.5 * wrap_angle(clip.heading_rad[f + 1] - clip.heading_rad[f])
        ground = pos[:, clip.root_joint, [0, 2]]
        dh_in, dp_in = step_offsets(clip.heading_rad[f], clip.ground_m[f], heading, ground)
        arrival = parts.add_meta(clip.acc_slow_g[2 * f + 1], dh_in, dp_in)
        arrays = dict(
            node_clip=np.full(len(f), ci, np.int32), node_clip2=np.full(len(f), -1, np.int32),
            node_frame=(f + 0.5).astype(np.float32), node_kind=np.full(len(f), NODE_SLOW, np.int8),
            node_label=np.full(len(f), label_names.index(clip.label), np.int16),
            node_positions_m=pos.astype(np.float32), node_heading_rad=heading, node_ground_m=ground,
            node_contacts=clip.contacts[f], node_arrival=arrival)
        if has_rot:
            arrays["node_rotations"] = quat.slerp(clip.local_rotations[f], clip.local_rotations[f + 1], 0.5).astype(
                np.float32)
            arrays["node_root_m"] = 0.5 * (clip.root_positions_m[f] + clip.root_positions_m[f + 1])
        slow = parts.add_nodes(**arrays)
        parts.add_edges(base + f, slow, EDGE_SLOWDOWN, arrival)
        dh_out, dp_out = step_offsets(heading, ground, clip.heading_rad[f + 1], clip.ground_m[f + 1])
        parts.add_edges(slow, base + f + 1, EDGE_SLOWDOWN, parts.add_meta(clip.acc_slow_g[2 * f + 2], dh_out, dp_out))
        g = np.flatnonzero(grounded[:-2] & grounded[1:-1] & grounded[2:])  # speed-up edge g -> g+2
        dh, dp = step_offsets(clip.heading_rad[g], clip.ground_m[g], clip.heading_rad[g + 2], clip.ground_m[g + 2])
        parts.add_edges(base + g, base + g + 2, EDGE_SPEEDUP, parts.add_meta(clip.acc_fast_g[g + 2], dh, dp))
