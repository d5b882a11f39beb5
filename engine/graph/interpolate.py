"""Interpolated motions (seed 000 section 4.2): blend similar stretches of two clips into new graph nodes.

For every pair of clips S, P: the pose similarity matrix (point-cloud distance of single poses, the same
closed form as the transitions) is thresholded at t_i and restricted to equal foot-contact states; the kept
cells are grouped into 8-connected components (scipy.ndimage.label); inside each component a DTW with
steps (1,1), (1,2), (2,1) -- local slope within [1/2, 2] -- aligns the two stretches, visiting kept cells only,
from the component's earliest kept cell to its latest. Alignments longer than `interp_min_length_s` become new
clips blended with even weights:

* body shape: each pose in its own root frame (origin under the root, facing +Z) is averaged (joint positions)
  and slerped half-way (local joint rotations, root rotation relative to heading);
* root path: the per-frame heading and local ground offsets of both stretches are averaged and integrated, so
  the blend moves like both parents (the same eq.-5 offsets the search uses);
* accelerations: the blend's own virtual sensors when the builder has a sensor model (graphs built from
  engine.mocap Motions), else the average of the two parents' readings at the aligned frames.

Each blend is wired in with entry edges from both parents' predecessor frames and exit edges to both parents'
successor frames, so a path can switch into and out of it wherever the parents could be.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from engine.mocap import quaternions as quat

from .clips import ClipData
from .config import GraphConfig
from .geometry import wrap_angle
from .parts import EDGE_INTERP, EDGE_NATURAL, NODE_INTERP, GraphParts
from .metadata import advance, step_offsets
from .poses import root_local
from .slope_dtw import HAVE_DTW_PYTHON, library_path
from .pointcloud import WindowFeatures, distance_matrix, window_features
from .transitions import contact_code

_EIGHT = np.ones((3, 3), dtype=bool)


def _yaw(angle_rad: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) of rotations about +Y by `angle_rad`."""
    return quat.from_rotvec(np.asarray(angle_rad)[..., None] * np.array([0.0, 1.0, 0.0]))


@dataclass(frozen=True)
class Alignment:
    """A DTW-aligned stretch: frame `a[k]` of clip `s` goes with frame `b[k]` of clip `p`."""

    s: int
    p: int
    a: np.ndarray
    b: np.ndarray
    distance_m: float = 0.0  # mean single-pose distance along the alignment (lower = a cleaner blend)


def slope_constrained_dtw(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Cheapest path from cell (0, 0) to the last cell using steps (1,1), (1,2), (2,1); inf cells are
    forbidden. Returns (rows, cols) of the path, or None if the corner cells are not connected."""
    n, m = cost.shape
    acc = np.full((n, m), np.inf)
    move = np.zeros((n, m), dtype=np.int8)  # 0: (1,1)  1: (1,2)  2: (2,1)
    acc[0, 0] = cost[0, 0]
    for i in range(1, n):
        cand = np.full((3, m), np.inf)
        cand[0, 1:] = acc[i - 1, :-1]
        cand[1, 2:] = acc[i - 1, :-2]
        if i >= 2:
            cand[2, 1:] = acc[i - 2, :-1]
        best = cand.argmin(axis=0)
        acc[i] = cost[i] + cand[best, np.arange(m)]
        move[i] = best
    if not np.isfinite(acc[-1, -1]):
        return None
    rows, cols = [n - 1], [m - 1]
    i, j = n - 1, m - 1
    steps = ((1, 1), (1, 2), (2, 1))
    while (i, j) != (0, 0):
        di, dj = steps[move[i, j]]
        i, j = i - di, j - dj
        rows.append(i)
        cols.append(j)
    return np.array(rows[::-1]), np.array(cols[::-1])


def find_alignments(clips: list[ClipData], config: GraphConfig, joint_weights: np.ndarray) -> list[Alignment]:
    """All blendable alignments between pairs of different clips (see module docstring)."""
    feats = [window_features(c.positions_m, np.arange(c.n_frames), 1, joint_weights) for c in clips]
    codes = [contact_code(c.contacts) for c in clips]
    min_len = int(np.ceil(config.interp_min_length_s * config.fps))
    out = []
    starts = np.cumsum([0] + [c.n_frames for c in clips])
    for s in range(len(clips) - 1):
        # one GEMM against all later clips at once: thousands of tiny per-pair GEMMs spend their time in
        # BLAS thread start-up instead of arithmetic
        later = WindowFeatures(*(np.concatenate([getattr(f, k) for f in feats[s + 1:]])
                                 for k in ("centres", "c", "u", "v", "y")))
        dist_all = distance_matrix(feats[s], later)
        for p in range(s + 1, len(clips)):
            dist = dist_all[:, starts[p] - starts[s + 1]:starts[p + 1] - starts[s + 1]]
            keep = (dist < config.interp_threshold_m) & (codes[s][:, None] == codes[p][None, :])
            if keep.sum() < min_len:
                continue
            labels, n_groups = ndimage.label(keep, structure=_EIGHT)
            for box_i, box in enumerate(ndimage.find_objects(labels), start=1):
                if box[0].stop - box[0].start < min_len or box[1].stop - box[1].start < min_len:
                    continue
                inside = labels[box] == box_i
                cells = np.argwhere(inside)
                first = cells[np.argmin(cells.sum(axis=1))]
                after = cells[np.all(cells >= first, axis=1)]  # the path must end below-right of its start
                last = after[np.argmax(after.sum(axis=1))]
                sub = np.where(inside, dist[box], np.inf)[first[0]:last[0] + 1, first[1]:last[1] + 1]
                path = library_path(sub) if HAVE_DTW_PYTHON else slope_constrained_dtw(sub)
                if path is None or len(path[0]) < min_len:
                    continue
                a = path[0] + box[0].start + first[0]
                b = path[1] + box[1].start + first[1]
                out.append(Alignment(s, p, a, b, float(sub[path].mean())))
    return out


def _blend(sc: ClipData, pc: ClipData, a: np.ndarray, b: np.ndarray) -> dict[str, np.ndarray]:
    """Arrays of the even-weight blend of S[a] and P[b] (positions, heading, ground, contacts, acc, rotations)."""
    local = 0.5 * (root_local(sc.positions_m[a], sc.ground_m[a], sc.heading_rad[a])
                   + root_local(pc.positions_m[b], pc.ground_m[b], pc.heading_rad[b]))
    pa = np.r_[max(a[0] - 1, 0), a[:-1]]
    pb = np.r_[max(b[0] - 1, 0), b[:-1]]
    dh_s, dp_s = step_offsets(sc.heading_rad[pa], sc.ground_m[pa], sc.heading_rad[a], sc.ground_m[a])
    dh_p, dp_p = step_offsets(pc.heading_rad[pb], pc.ground_m[pb], pc.heading_rad[b], pc.ground_m[b])
    dh, dp = 0.5 * (dh_s + dh_p), 0.5 * (dp_s + dp_p)
    ground = np.empty((len(a), 2))
    heading = np.empty(len(a))
    ground[0], heading[0] = sc.ground_m[a[0]], sc.heading_rad[a[0]]
    for k in range(1, len(a)):
        ground[k], heading[k] = advance(ground[k - 1], heading[k - 1], dp[k], dh[k])
    pos = local.copy()
    c, s_ = np.cos(heading)[:, None], np.sin(heading)[:, None]
    x, z = local[..., 0], local[..., 2]
    pos[..., 0] = x * c + z * s_ + ground[:, 0, None]
    pos[..., 2] = -x * s_ + z * c + ground[:, 1, None]
    out = dict(positions=pos, heading=wrap_angle(heading), ground=ground, contacts=sc.contacts[a],
               acc=0.5 * (sc.acc_g[a] + pc.acc_g[b]), dh=dh, dp=dp)
    if sc.local_rotations is not None and pc.local_rotations is not None:
        rs, rp = sc.local_rotations[a].copy(), pc.local_rotations[b].copy()
        rs[:, 0] = quat.multiply(_yaw(-sc.heading_rad[a]), rs[:, 0])  # root rotation relative to heading
        rp[:, 0] = quat.multiply(_yaw(-pc.heading_rad[b]), rp[:, 0])
        rot = quat.slerp(rs, rp, 0.5)
        rot[:, 0] = quat.multiply(_yaw(heading), rot[:, 0])
        out["rotations"] = rot
        out["root"] = pos[:, sc.root_joint]
    return out


def cap_alignments(alignments: list[Alignment], max_frames: int) -> list[Alignment]:
    """The cleanest alignments (lowest mean distance first) whose frames add up to at most `max_frames`: similar
    repetitive clips (dozens of walks) otherwise blend every pair -- 3.6 M new poses on Bandai dataset 2's 76 k
    frames, 10 GB to build and a search below real time (issue 11)."""
    kept, total = set(), 0
    for i in sorted(range(len(alignments)), key=lambda i: alignments[i].distance_m):
        if total + len(alignments[i].a) <= max_frames:
            kept.add(i)
            total += len(alignments[i].a)
    return [al for i, al in enumerate(alignments) if i in kept]  # in the order found (node ids stay stable)


def add_interpolated_motions(parts: GraphParts, clips: list[ClipData], offsets: np.ndarray, config: GraphConfig,
                             joint_weights: np.ndarray, label_names: list[str], sensor_model=None) -> dict:
    """Append the blends (capped at `config.interp_max_share` x the database's frames, cleanest first) as chains
    of new nodes with entry/exit edges; returns what was found and kept."""
    has_rot = "node_rotations" in parts.node
    arrival_all = np.concatenate(parts.node["node_arrival"][: len(clips)])
    found = find_alignments(clips, config, joint_weights)
    n_frames = int(sum(c.n_frames for c in clips))
    cap = int(config.interp_max_share * n_frames) if config.interp_max_share is not None else n_frames * len(clips)
    alignments = cap_alignments(found, cap)
    for al in alignments:
        sc, pc = clips[al.s], clips[al.p]
        bl = _blend(sc, pc, al.a, al.b)
        k = len(al.a)
        if sensor_model is not None and "rotations" in bl and k >= 3:
            bl["acc"] = sensor_model(bl["root"], bl["rotations"])  # the blend's own virtual sensors
        rows = parts.add_meta(bl["acc"], bl["dh"], bl["dp"])
        arrays = dict(
            node_clip=np.full(k, al.s, np.int32), node_clip2=np.full(k, al.p, np.int32),
            node_frame=al.a.astype(np.float32), node_kind=np.full(k, NODE_INTERP, np.int8),
            node_label=np.full(k, label_names.index(sc.label), np.int16),
            node_positions_m=bl["positions"].astype(np.float32), node_heading_rad=bl["heading"],
            node_ground_m=bl["ground"], node_contacts=bl["contacts"], node_arrival=rows)
        if has_rot:
            arrays["node_rotations"] = bl["rotations"].astype(np.float32)
            arrays["node_root_m"] = bl["root"]
        ids = parts.add_nodes(**arrays)
        parts.add_edges(ids[:-1], ids[1:], EDGE_NATURAL, rows[1:])
        entries = [offsets[c] + f - 1 for c, f in ((al.s, al.a[0]), (al.p, al.b[0])) if f > 0]
        parts.add_edges(np.array(entries, dtype=np.int64), np.full(len(entries), ids[0]), EDGE_INTERP,
                        np.full(len(entries), rows[0]))
        exits = [offsets[c] + f + 1 for c, f in ((al.s, al.a[-1]), (al.p, al.b[-1]))
                 if f + 1 < clips[c].n_frames]
        exits = np.array(exits, dtype=np.int64)
        parts.add_edges(np.full(len(exits), ids[-1]), exits, EDGE_INTERP, arrival_all[exits])
    return {"alignments_found": len(found), "frames_found": int(sum(len(al.a) for al in found)),
            "alignments_kept": len(alignments), "frames_kept": int(sum(len(al.a) for al in alignments)),
            "cap_frames": cap}
