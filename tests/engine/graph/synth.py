"""Synthetic clips with exact answers for the motion-graph tests.

A "gait" clip: a 5-joint stick figure whose root walks along a heading while two legs swing; the contact state
alternates with a known period, so contact-change frames are known exactly. Accelerations are arbitrary but
deterministic per (clip, frame), which makes every metadata row distinct: a path's readings identify it.
"""
from __future__ import annotations

import numpy as np

from engine.graph.clips import ClipData
from engine.graph.geometry import rotate_points_y


def gait_clip(name: str, n_frames: int = 90, period: int = 15, phase: int = 0, heading0: float = 0.0,
              turn_rate: float = 0.0, speed: float = 0.04, origin=(0.0, 0.0), n_sensors: int = 2,
              seed: int = 0, label: str = "walk") -> ClipData:
    """A walking stick figure. Contacts: frames [0, period/2) of each period left foot down, else right."""
    f = np.arange(n_frames)
    heading = heading0 + turn_rate * f
    step = np.stack([np.sin(heading), np.cos(heading)], axis=1) * speed
    ground = np.asarray(origin, float) + np.concatenate([[np.zeros(2)], np.cumsum(step[1:], axis=0)])
    swing = np.sin(2 * np.pi * (f + phase) / period)
    local = np.zeros((n_frames, 5, 3))
    local[:, 0] = [0.0, 1.0, 0.0]  # root
    local[:, 1] = [0.0, 1.6, 0.0]  # head
    local[:, 2] = [0.1, 0.5, 0.0]  # left knee
    local[:, 3] = np.stack([np.full(n_frames, 0.1), np.zeros(n_frames), 0.3 * swing], axis=1)  # left foot
    local[:, 4] = np.stack([np.full(n_frames, -0.1), np.zeros(n_frames), -0.3 * swing], axis=1)  # right foot
    positions = np.stack([rotate_points_y(local[i], heading[i]) for i in range(n_frames)])
    positions[:, :, 0] += ground[:, 0, None]
    positions[:, :, 2] += ground[:, 1, None]
    left = ((f + phase) % period) < period // 2
    contacts = np.stack([left, ~left], axis=1)
    rng = np.random.default_rng(seed)
    acc = rng.normal(0.0, 1.0, (n_frames, n_sensors, 3))
    return ClipData(name=name, positions_m=positions, contacts=contacts, heading_rad=heading, acc_g=acc,
                    label=label, acc_slow_g=rng.normal(0.0, 1.0, (2 * n_frames - 1, n_sensors, 3)),
                    acc_fast_g=rng.normal(0.0, 1.0, (n_frames, n_sensors, 3)))


def rigid_copy(clip: ClipData, name: str, angle_rad: float, shift_xz, seed: int = 99) -> ClipData:
    """The same poses rotated about +Y and shifted on the ground (point-cloud distance 0 to the original)."""
    pos = rotate_points_y(clip.positions_m, angle_rad)
    pos[..., 0] += shift_xz[0]
    pos[..., 2] += shift_xz[1]
    rng = np.random.default_rng(seed)
    return ClipData(name=name, positions_m=pos, contacts=clip.contacts.copy(),
                    heading_rad=clip.heading_rad + angle_rad, acc_g=rng.normal(0, 1, clip.acc_g.shape),
                    label=clip.label, acc_slow_g=rng.normal(0, 1, clip.acc_slow_g.shape),
                    acc_fast_g=rng.normal(0, 1, clip.acc_fast_g.shape))


def walk_path(graph, start_node: int, n_samples: int, rng: np.random.Generator, prefer_kind: int | None = None):
    """A random walk through the graph (taking `prefer_kind` edges whenever possible); returns (nodes, edges)
    with edges[0] = -1. Restarts are not allowed, so the caller picks a long-lived start."""
    out_edges: dict[int, list[int]] = {}
    for e, s in enumerate(graph.edge_src):
        out_edges.setdefault(int(s), []).append(e)
    nodes, edges = [start_node], [-1]
    while len(nodes) < n_samples:
        choices = out_edges.get(nodes[-1], [])
        if not choices:
            raise RuntimeError("walk hit a dead end")
        pref = [e for e in choices if prefer_kind is not None and graph.edge_kind[e] == prefer_kind]
        e = int(rng.choice(pref if pref else choices))
        edges.append(e)
        nodes.append(int(graph.edge_dst[e]))
    return np.array(nodes), np.array(edges)


def observe(graph, nodes, edges, ground0, heading0):
    """Exact readings for a path: arrival-row acc for the first sample, edge metadata after; global position and
    heading integrated from (ground0, heading0) as eq. 5 does."""
    from engine.graph.metadata import advance

    rows = np.r_[graph.node_arrival[nodes[0]], graph.edge_meta[edges[1:]]]
    acc = graph.meta_acc_g[rows].astype(float)
    ground = np.empty((len(nodes), 2))
    heading = np.empty(len(nodes))
    ground[0], heading[0] = ground0, heading0
    for t in range(1, len(nodes)):
        ground[t], heading[t] = advance(ground[t - 1], heading[t - 1], graph.meta_dpos_m[rows[t]],
                                        graph.meta_dheading_rad[rows[t]])
    return acc, ground, heading
