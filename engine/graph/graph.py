"""The motion graph as flat numpy arrays: nodes are database poses at the graph rate, edges are sorted by
destination so the search can take minima over incoming edges with `np.minimum.reduceat`.

Metadata rows: `node_arrival[n]` is the row describing *arriving at node n along its own clip* (the natural
step into n); natural edges and transitions into n both use it, since a transition i-1 -> j replays the
motion j-1 -> j. Other rows belong to edges with their own motion (MSV speed-up/slow-down steps, entries into
interpolated clips). The first sample of a search is scored against the arrival row of each start node.
"""
from __future__ import annotations

import json
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from engine.errors import MalformedFileError
from engine.safe_load import parse_json
from engine.mocap.skeleton import Skeleton

from .clips import ClipData
from .components import ComponentReport, component_labels, largest_component
from .config import GraphConfig
from .metadata import step_offsets
from .parts import EDGE_KIND_NAMES, EDGE_NATURAL, EDGE_TRANSITION, NODE_ORIGINAL, GraphParts
from .transitions import clip_end_transitions, find_transitions

FORMAT_VERSION = 1
_NON_ARRAYS = {"config", "clip_names", "label_names", "skeleton", "build_report"}


@dataclass
class MotionGraph:
    """Nodes, edges (sorted by dst) and edge metadata. Build with `MotionGraph.build` / `build_from_clips`."""

    config: GraphConfig
    clip_names: list[str]
    label_names: list[str]
    # nodes
    node_clip: np.ndarray  # (N,) int32 source clip
    node_clip2: np.ndarray  # (N,) int32 second source clip of interpolated nodes, else -1
    node_frame: np.ndarray  # (N,) float32 frame in the source clip (x.5 for slow-down nodes)
    node_kind: np.ndarray  # (N,) int8 NODE_*
    node_label: np.ndarray  # (N,) int16 index into label_names
    node_positions_m: np.ndarray  # (N, J, 3) float32 joint positions in the source clip's frame
    node_heading_rad: np.ndarray  # (N,) float64 root heading in the source clip's frame
    node_ground_m: np.ndarray  # (N, 2) float64 root (x, z)
    node_contacts: np.ndarray  # (N, 2) bool
    node_arrival: np.ndarray  # (N,) int32 metadata row of the natural step into the node
    # edges, sorted by (dst, src)
    edge_src: np.ndarray  # (E,) int32
    edge_dst: np.ndarray  # (E,) int32
    edge_kind: np.ndarray  # (E,) int8 EDGE_*
    edge_meta: np.ndarray  # (E,) int32 row into meta_*
    # metadata rows
    meta_acc_g: np.ndarray  # (M, S, 3) float32
    meta_dheading_rad: np.ndarray  # (M,) float64
    meta_dpos_m: np.ndarray  # (M, 2) float64, local frame of the edge's source
    node_rotations: np.ndarray | None = None  # (N, J, 4) local joint rotations (w, x, y, z)
    node_root_m: np.ndarray | None = None  # (N, 3) root position in the source clip's frame
    skeleton: Skeleton | None = None  # the database skeleton, so a synthesis can be written as BVH
    sensor_rotations: np.ndarray | None = None  # (S, 3, 3) each sensor's axes -> its joint frame as the graph was
    # built (a calibrated strapping: engine.mocap.calibrated); None = the standard placements' (orientation_term)
    build_report: dict | None = None  # what the builder's component step did (components.ComponentReport)

    # ----- sizes and search helpers -------------------------------------------------------------
    @property
    def n_nodes(self) -> int:
        return int(len(self.node_clip))

    @property
    def n_edges(self) -> int:
        return int(len(self.edge_src))

    @property
    def n_sensors(self) -> int:
        return int(self.meta_acc_g.shape[1])

    def segments(self) -> tuple[np.ndarray, np.ndarray]:
        """(nodes with incoming edges, start index of each one's run of incoming edges) for reduceat."""
        starts = np.flatnonzero(np.r_[True, self.edge_dst[1:] != self.edge_dst[:-1]]) if self.n_edges else \
            np.zeros(0, dtype=np.int64)
        return self.edge_dst[starts].astype(np.int64), starts.astype(np.int64)

    def edge_index(self, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
        """Index of the edge src -> dst for each pair (edges are unique per pair); raises if one is missing."""
        keys = self.edge_dst.astype(np.int64) * self.n_nodes + self.edge_src
        want = np.asarray(dst, dtype=np.int64) * self.n_nodes + np.asarray(src, dtype=np.int64)
        pos = np.searchsorted(keys, want)
        pos = np.minimum(pos, len(keys) - 1)
        if len(keys) == 0 or np.any(keys[pos] != want):
            raise KeyError("no such edge in the graph")
        return pos

    def label_mask(self, label: str) -> np.ndarray:
        """(N,) bool: nodes whose source clip carries `label` (for human constraints)."""
        if label not in self.label_names:
            raise KeyError(f"label {label!r} not in graph labels {self.label_names}")
        return self.node_label == self.label_names.index(label)

    def summary(self) -> dict:
        kinds = np.bincount(self.edge_kind, minlength=len(EDGE_KIND_NAMES))
        return {"nodes": self.n_nodes, "edges": self.n_edges, "clips": len(self.clip_names),
                "sensors": self.n_sensors, "meta_rows": int(len(self.meta_dheading_rad)),
                **{f"edges_{name}": int(k) for name, k in zip(EDGE_KIND_NAMES, kinds)}}

    # ----- leave-one-out ---------------------------------------------------------------------------
    def without_clips(self, clip_ids: list[int]) -> "MotionGraph":
        """A copy without every node derived from the given clips (incl. interpolated nodes that used them)."""
        drop = np.isin(self.node_clip, clip_ids) | np.isin(self.node_clip2, clip_ids)
        keep = ~drop
        if self.config.connect:  # a connected graph stays connected: what the removal cut off is pruned too
            sub = keep[self.edge_src] & keep[self.edge_dst]
            keep &= largest_component(self.edge_src[sub], self.edge_dst[sub], self.n_nodes)
        return self.subgraph(keep)

    def subgraph(self, keep: np.ndarray) -> "MotionGraph":
        """A copy with only the nodes where `keep` (N,) is True and the edges between them (ids renumbered in
        order, so edges stay sorted by (dst, src))."""
        keep = np.asarray(keep, dtype=bool)
        new_id = np.cumsum(keep) - 1
        ekeep = keep[self.edge_src] & keep[self.edge_dst]
        node_arrays = {f.name: getattr(self, f.name) for f in fields(self) if f.name.startswith("node_")}
        kwargs = {k: (v[keep] if v is not None else None) for k, v in node_arrays.items()}
        # metadata rows stay as they are (rows of dropped nodes are simply no longer referenced)
        return MotionGraph(
            config=self.config, clip_names=self.clip_names, label_names=self.label_names, skeleton=self.skeleton,
            build_report=self.build_report, sensor_rotations=self.sensor_rotations, **kwargs,
            edge_src=new_id[self.edge_src[ekeep]].astype(np.int32),
            edge_dst=new_id[self.edge_dst[ekeep]].astype(np.int32),
            edge_kind=self.edge_kind[ekeep], edge_meta=self.edge_meta[ekeep],
            meta_acc_g=self.meta_acc_g, meta_dheading_rad=self.meta_dheading_rad, meta_dpos_m=self.meta_dpos_m)

    # ----- persistence -----------------------------------------------------------------------------
    def save(self, path: str | Path) -> None:
        """One .npz holding the arrays plus a JSON header (config, clip and label names)."""
        header = {"format_version": FORMAT_VERSION, "config": json.loads(self.config.to_json()),
                  "clip_names": self.clip_names, "label_names": self.label_names,
                  "skeleton_names": list(self.skeleton.names) if self.skeleton is not None else None,
                  "build_report": self.build_report}
        arrays = {f.name: getattr(self, f.name) for f in fields(self)
                  if f.name not in _NON_ARRAYS and getattr(self, f.name) is not None}
        if self.skeleton is not None:
            arrays.update(skeleton_parents=self.skeleton.parents, skeleton_offsets_m=self.skeleton.offsets_m,
                          skeleton_end_site=self.skeleton.end_site)
        with open(path, "wb") as fh:
            np.savez(fh, header_json=np.array(json.dumps(header)), **arrays)

    @classmethod
    def load(cls, path: str | Path) -> "MotionGraph":
        from .input_checks import graph_arrays_problem, open_npz

        with open_npz(Path(path)) as data:
            try:  # any parse failure of a damaged or foreign file becomes one error naming the file
                if "header_json" not in data:
                    raise MalformedFileError(path, None, "missing 'header_json': not a motion graph file")
                header = parse_json(str(data["header_json"]), f"{path}: 'header_json'")
                if not isinstance(header, dict):
                    raise MalformedFileError(path, None, "'header_json' is not a JSON object")
                if header.get("format_version") != FORMAT_VERSION:
                    raise MalformedFileError(path, None, f"unsupported graph format {header.get('format_version')}")
                names = {f.name for f in fields(cls)} - _NON_ARRAYS
                optional = {"node_rotations", "node_root_m", "sensor_rotations"}
                missing = sorted(names - optional - set(data.files))
                if missing:
                    raise MalformedFileError(path, None, f"missing arrays: {', '.join(missing)}")
                arrays = {k: data[k] for k in names if k in data.files}
                skeleton = None
                if header.get("skeleton_names"):
                    parents = data["skeleton_parents"]
                    problem = graph_arrays_problem(arrays, len(header["skeleton_names"]), parents)
                    if problem:
                        raise MalformedFileError(path, None, problem)
                    skeleton = Skeleton(tuple(header["skeleton_names"]), parents, data["skeleton_offsets_m"],
                                        data["skeleton_end_site"])
                graph = cls(config=GraphConfig(**header["config"]), clip_names=header["clip_names"],
                            label_names=header["label_names"], skeleton=skeleton,
                            build_report=header.get("build_report"), **arrays)
            except (ValueError, TypeError, KeyError, OSError, EOFError, zipfile.BadZipFile) as exc:
                if isinstance(exc, MalformedFileError):
                    raise
                raise MalformedFileError(path, None, f"not a valid motion graph ({type(exc).__name__}: {exc})") from None
        problem = graph_arrays_problem(arrays, None, None) or graph.inconsistency()
        if problem:
            raise MalformedFileError(path, None, problem)
        return graph

    def inconsistency(self) -> str | None:
        """What is wrong with the arrays (None if they fit together): a damaged file must not crash a search."""
        n, e, m = self.n_nodes, self.n_edges, len(self.meta_dheading_rad)
        node_arrays = [self.node_clip2, self.node_frame, self.node_kind, self.node_label, self.node_heading_rad,
                       self.node_arrival, self.node_positions_m, self.node_ground_m, self.node_contacts]
        if any(len(a) != n for a in node_arrays):
            return "node arrays have different lengths"
        if any(len(a) != e for a in (self.edge_dst, self.edge_kind, self.edge_meta)):
            return "edge arrays have different lengths"
        if len(self.meta_acc_g) != m or len(self.meta_dpos_m) != m:
            return "metadata arrays have different lengths"
        ends = (self.edge_src, self.edge_dst)
        if e and (min(a.min() for a in ends) < 0 or max(a.max() for a in ends) >= n):
            return "edge endpoints outside the node range"
        if (e and (self.edge_meta.min() < 0 or self.edge_meta.max() >= m)) or (
                n and (self.node_arrival.min() < 0 or self.node_arrival.max() >= m)):
            return "metadata row ids outside the metadata table"
        key = self.edge_dst.astype(np.int64) * n + self.edge_src
        if np.any(np.diff(key) <= 0):
            return "edges are not sorted by (dst, src) or not unique"
        return None

    # ----- construction ----------------------------------------------------------------------------
    @classmethod
    def build(cls, motions: list, placements: list, config: GraphConfig | None = None,
              labels: list[str] | None = None) -> "MotionGraph":
        """Build from engine.mocap Motions (one skeleton) and SensorPlacements; `labels` = one action label per
        clip for human constraints (see engine.graph.mocap_adapter)."""
        from .mocap_adapter import clips_from_motions, mocap_sensor_model

        config = config or GraphConfig()
        if not config.sensor_names:
            config.sensor_names = [p.name for p in placements]
        graph = build_from_clips(clips_from_motions(motions, placements, config, labels), config,
                                 mocap_sensor_model(motions[0].skeleton, placements, config.fps))
        graph.skeleton = motions[0].skeleton
        graph.sensor_rotations = np.stack([p.rotation for p in placements]).astype(float)
        return graph


def _original_nodes(parts: GraphParts, clips: list[ClipData], label_names: list[str]) -> np.ndarray:
    """Add every clip frame as a node plus its natural arrival row; returns clip offsets (C+1,)."""
    offsets = np.concatenate([[0], np.cumsum([c.n_frames for c in clips])]).astype(np.int64)
    has_rot = all(c.local_rotations is not None for c in clips)
    for ci, clip in enumerate(clips):
        f = clip.n_frames
        arrays = dict(
            node_clip=np.full(f, ci, np.int32), node_clip2=np.full(f, -1, np.int32),
            node_frame=np.arange(f, dtype=np.float32), node_kind=np.full(f, NODE_ORIGINAL, np.int8),
            node_label=np.full(f, label_names.index(clip.label), np.int16),
            node_positions_m=clip.positions_m.astype(np.float32), node_heading_rad=clip.heading_rad.astype(float),
            node_ground_m=clip.ground_m.astype(float), node_contacts=clip.contacts)
        prev = np.r_[0, np.arange(f - 1)]  # frame 0 "arrives" from itself: zero offsets
        dh, dp = step_offsets(clip.heading_rad[prev], clip.ground_m[prev], clip.heading_rad, clip.ground_m)
        arrays["node_arrival"] = parts.add_meta(clip.acc_g, dh, dp)
        if has_rot:
            arrays["node_rotations"] = clip.local_rotations.astype(np.float32)
            arrays["node_root_m"] = clip.root_positions_m.astype(float)
        parts.add_nodes(**arrays)
        ids = np.arange(offsets[ci] + 1, offsets[ci + 1])
        parts.add_edges(ids - 1, ids, EDGE_NATURAL, arrays["node_arrival"][1:])
    return offsets


SensorModel = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""(root positions (K, 3) m, local rotations (K, J, 4)) of a K-frame motion at the graph rate -> virtual
accelerations (K, S, 3) g: lets interpolated motions get their own simulated sensor readings."""


def build_from_clips(clips: list[ClipData], config: GraphConfig,
                     sensor_model: SensorModel | None = None) -> MotionGraph:
    """Assemble the graph: original frames, natural edges, transitions, then optional MSV / interpolation.
    Without `sensor_model` interpolated motions read the mean of their parents' accelerations."""
    if not clips:
        raise ValueError("cannot build a motion graph from zero clips")
    n_joints = {c.positions_m.shape[1] for c in clips}
    n_sensors = {c.acc_g.shape[1] for c in clips}
    if len(n_joints) != 1 or len(n_sensors) != 1:
        raise ValueError("all clips must share one skeleton and one sensor set")
    joint_weights = np.ones(n_joints.pop()) if config.joint_weights is None else np.asarray(config.joint_weights)
    label_names = sorted({c.label for c in clips})
    parts = GraphParts()
    offsets = _original_nodes(parts, clips, label_names)
    idle = config.idle_spacing_frames if config.connect else 0
    tr = find_transitions(clips, config.window_frames, joint_weights, config.transition_threshold_m,
                          config.min_jump_frames, config.max_transitions_per_frame, idle_spacing_frames=idle)
    arrival = np.concatenate(parts.node["node_arrival"])
    parts.add_edges(tr.src_frame - 1, tr.dst_frame, EDGE_TRANSITION, arrival[tr.dst_frame])
    report = _connect(parts, clips, config, joint_weights, arrival) if config.connect else None
    if config.msv:
        from .msv import add_speed_variations

        add_speed_variations(parts, clips, offsets, label_names)
    interp = None
    if config.interp:
        from .interpolate import add_interpolated_motions

        interp = add_interpolated_motions(parts, clips, offsets, config, joint_weights, label_names, sensor_model)
    graph = assemble(parts, clips, config, label_names)
    if interp is not None:
        graph.build_report = {"interpolation": interp}
    if report is None:
        return graph
    keep = largest_component(graph.edge_src, graph.edge_dst, graph.n_nodes)
    report.pruned_nodes = int((~keep).sum())
    report.pruned_frames = int((~keep & (graph.node_kind == NODE_ORIGINAL)).sum())
    pruned = graph.subgraph(keep)
    report.pruned_edges = graph.n_edges - pruned.n_edges
    report.clips_kept = int(len(np.unique(pruned.node_clip)))
    report.clips_total = len(clips)
    pruned.build_report = {**(graph.build_report or {}), "component": report.as_dict()}
    return pruned


def _connect(parts: GraphParts, clips: list[ClipData], config: GraphConfig, joint_weights: np.ndarray,
             arrival: np.ndarray) -> ComponentReport:
    """The component step's first half (see engine/graph/components.py): relaxed transitions for the frames
    outside the largest strongly connected component of the natural + transition edges, threshold by threshold,
    until the component holds `min_component_share` of the frames and part of every clip (on Bandai dataset 1 the
    share alone was reached at 0.12 m with 4 gesture clips still outside)."""
    n = int(sum(c.n_frames for c in clips))
    frame_clip = np.repeat(np.arange(len(clips)), [c.n_frames for c in clips])
    src, dst = np.concatenate(parts.edge["src"]), np.concatenate(parts.edge["dst"])
    labels = component_labels(src, dst, n)
    report = ComponentReport(frames=n, share_before=float(np.mean(labels == 0)))
    used = []
    for threshold in config.connect_thresholds_m:
        if np.mean(labels == 0) >= config.min_component_share and \
                len(np.unique(frame_clip[labels == 0])) == len(clips):
            break
        for tr in (find_transitions(clips, config.window_frames, joint_weights, threshold, config.min_jump_frames,
                                    config.connect_max_per_frame, idle_spacing_frames=config.idle_spacing_frames,
                                    components=labels),
                   clip_end_transitions(clips, config.window_frames, joint_weights, threshold,
                                        config.connect_max_per_frame, labels)):
            parts.add_edges(tr.src_frame - 1, tr.dst_frame, EDGE_TRANSITION, arrival[tr.dst_frame])
            report.relaxed_transitions += len(tr.src_frame)
            src, dst = np.r_[src, tr.src_frame - 1], np.r_[dst, tr.dst_frame]
        used.append(float(threshold))
        labels = component_labels(src, dst, n)
    report.share_connected = float(np.mean(labels == 0))
    report.thresholds_used_m = tuple(used)
    return report


def assemble(parts: GraphParts, clips: list[ClipData], config: GraphConfig, label_names: list[str]) -> MotionGraph:
    """Concatenate the parts, drop duplicate (src, dst) edges (first added wins) and sort edges by dst."""
    node = {k: np.concatenate(v) for k, v in parts.node.items()}
    src = np.concatenate(parts.edge["src"])
    dst = np.concatenate(parts.edge["dst"])
    kind = np.concatenate(parts.edge["kind"])
    meta = np.concatenate(parts.edge["meta"])
    key = dst * parts.n_nodes + src
    _, first = np.unique(key, return_index=True)  # unique sorts by key = (dst, src)
    return MotionGraph(
        config=config, clip_names=[c.name for c in clips], label_names=label_names,
        node_clip=node["node_clip"], node_clip2=node["node_clip2"], node_frame=node["node_frame"],
        node_kind=node["node_kind"], node_label=node["node_label"], node_positions_m=node["node_positions_m"],
        node_heading_rad=node["node_heading_rad"], node_ground_m=node["node_ground_m"],
        node_contacts=node["node_contacts"].astype(bool), node_arrival=node["node_arrival"].astype(np.int32),
        node_rotations=node.get("node_rotations"), node_root_m=node.get("node_root_m"),
        edge_src=src[first].astype(np.int32), edge_dst=dst[first].astype(np.int32), edge_kind=kind[first],
        edge_meta=meta[first].astype(np.int32),
        meta_acc_g=np.concatenate(parts.meta["acc"]).astype(np.float32),
        meta_dheading_rad=np.concatenate(parts.meta["dheading"]).astype(float),
        meta_dpos_m=np.concatenate(parts.meta["dpos"]).astype(float))
