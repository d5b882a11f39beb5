"""Transition candidates: contact-change frames joined by point-cloud local minima below a threshold.

Following Safonova & Hodgins (as seed 000 does), a transition may only happen where the foot-contact state
changes, and only between frames with the same contact state: a candidate is the first frame of a new
contact state. A transition "i ~ j" means pose j can stand in for pose i, so the graph gets the edge
(i - 1) -> j: the path leaves i's clip just before i and continues with j's clip.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine import progress
from .clips import ClipData
from .pointcloud import WindowFeatures, distance_matrix, window_features


@dataclass(frozen=True)
class Transitions:
    """Chosen transitions as global frame indices (into the concatenation of all clips)."""

    src_frame: np.ndarray  # (K,) int64: frame i whose place is taken (edge leaves from i - 1)
    dst_frame: np.ndarray  # (K,) int64: frame j entered instead of i
    distance_m: np.ndarray  # (K,) RMS point-cloud distance


def contact_change_frames(contacts: np.ndarray, window_frames: int) -> np.ndarray:
    """Frames (of one clip) where the contact state differs from the previous frame and a full window fits."""
    change = np.flatnonzero(np.any(contacts[1:] != contacts[:-1], axis=1)) + 1
    half = window_frames // 2
    n = contacts.shape[0]
    return change[(change - half >= 0) & (change + (window_frames - half) <= n)]


def idle_frames(contacts: np.ndarray, window_frames: int, spacing_frames: int) -> np.ndarray:
    """Extra candidates inside long runs of one contact state (standing, gesturing, a clip's idle start and end):
    every `spacing_frames` frames of a run at least 2 x spacing long, plus the run's last frame whose window
    fits (so a clip's idle end can be left). A clip that never changes contact state (a bow, a punch from a planted stance) otherwise has
    no candidate at all and can never be entered or left; nothing changes for gait, whose runs are short."""
    if spacing_frames <= 0:
        return np.zeros(0, dtype=np.int64)
    n = contacts.shape[0]
    change = np.flatnonzero(np.any(contacts[1:] != contacts[:-1], axis=1)) + 1
    bounds = np.r_[0, change, n]
    half = window_frames // 2
    lo, hi = max(half, 1), n - (window_frames - half)  # first / last frame whose window fits (and has a frame before)
    out = [np.r_[np.arange(max(a, lo), min(b, hi + 1), spacing_frames), min(b - 1, hi)]
           for a, b in zip(bounds[:-1], bounds[1:]) if b - a >= 2 * spacing_frames]
    frames = np.unique(np.concatenate(out)) if out else np.zeros(0, dtype=np.int64)
    return frames[(frames >= lo) & (frames <= hi)]


def contact_code(contacts: np.ndarray) -> np.ndarray:
    """Contact state as one small integer per frame (left + 2 * right), for equality tests."""
    return contacts[..., 0].astype(np.int8) + 2 * contacts[..., 1].astype(np.int8)


def find_transitions(clips: list[ClipData], window_frames: int, joint_weights: np.ndarray,
                     threshold_m: float, min_jump_frames: int, max_per_frame: int = 0,
                     block_rows: int = 1024, idle_spacing_frames: int = 0,
                     components: np.ndarray | None = None) -> Transitions:
    """All transitions between contact-change frames of `clips` (including within one clip).

    A pair is kept when both frames have the same contact state, the distance is below `threshold_m`, and the
    distance is a local minimum of the candidate-by-candidate matrix (4-neighbourhood, neighbours taken only
    within the same clip, as Kovar keeps local minima of the frame-by-frame matrix). With `max_per_frame` > 0
    only that many of the closest transitions leave each frame (repetitive locomotion otherwise links every
    step to nearly every similar step of every other clip). `idle_spacing_frames` > 0 adds `idle_frames`
    candidates. `components` (strongly connected component label per global frame, the largest labelled 0):
    keep only transitions i ~ j that join two different components, one of them not the largest -- the component
    step uses it to connect what lies outside the largest component, and nothing else."""
    offsets = np.concatenate([[0], np.cumsum([c.n_frames for c in clips])])
    feats, glob, clip_id, code = [], [], [], []
    for ci, clip in enumerate(clips):
        cand = np.union1d(contact_change_frames(clip.contacts, window_frames),
                          idle_frames(clip.contacts, window_frames, idle_spacing_frames))
        if len(cand) == 0:
            continue
        feats.append(window_features(clip.positions_m, cand, window_frames, joint_weights))
        glob.append(cand + offsets[ci])
        clip_id.append(np.full(len(cand), ci))
        code.append(contact_code(clip.contacts[cand]))
    if not feats:
        empty = np.zeros(0, dtype=np.int64)
        return Transitions(empty, empty, np.zeros(0))
    allf = WindowFeatures(centres=np.concatenate(glob), c=np.concatenate([f.c for f in feats]),
                          u=np.concatenate([f.u for f in feats]), v=np.concatenate([f.v for f in feats]),
                          y=np.concatenate([f.y for f in feats]))
    glob_idx = np.concatenate(glob)
    clip_id = np.concatenate(clip_id)
    code = np.concatenate(code)
    n = len(glob_idx)
    nb_same = clip_id[1:] == clip_id[:-1]  # candidate k and k+1 belong to the same clip
    rows_out, cols_out, dist_out = [], [], []
    # row blocks (+1 halo row each side) bound the memory to O(block * n)
    for r0 in progress.bar(range(0, n, block_rows), desc="transitions", unit="block"):
        r1 = min(n, r0 + block_rows)
        lo, hi = max(0, r0 - 1), min(n, r1 + 1)
        rows = np.arange(lo, hi)
        dist = distance_matrix(_rows(allf, lo, hi), allf)
        masked = dist.copy()
        masked[code[rows, None] != code[None, :]] = np.inf
        same_clip = clip_id[rows, None] == clip_id[None, :]
        masked[same_clip & (np.abs(glob_idx[rows, None] - glob_idx[None, :]) < min_jump_frames)] = np.inf
        keep = masked < threshold_m
        # local minimum along both axes, comparing only with neighbours of the same clip
        left = np.full_like(masked, np.inf)
        left[:, 1:] = np.where(nb_same[None, :], masked[:, :-1], np.inf)
        right = np.full_like(masked, np.inf)
        right[:, :-1] = np.where(nb_same[None, :], masked[:, 1:], np.inf)
        up = np.full_like(masked, np.inf)
        up[1:] = np.where(nb_same[rows[:-1], None], masked[:-1], np.inf)
        down = np.full_like(masked, np.inf)
        down[:-1] = np.where(nb_same[rows[:-1], None], masked[1:], np.inf)
        keep &= (masked <= left) & (masked <= right) & (masked <= up) & (masked <= down)
        keep[: r0 - lo] = False  # halo rows belong to the neighbouring blocks
        keep[keep.shape[0] - (hi - r1):] = False
        if components is not None:
            a, b = components[glob_idx[rows] - 1][:, None], components[glob_idx][None, :]
            keep &= (a != b) & ((a != 0) | (b != 0))
        r, c = np.nonzero(keep)
        if max_per_frame > 0 and len(r):
            order = np.lexsort((dist[r, c], r))  # by row, then distance
            r, c = r[order], c[order]
            first = np.searchsorted(r, r)  # index of each row's first kept entry
            rank = np.arange(len(r)) - first
            r, c = r[rank < max_per_frame], c[rank < max_per_frame]
        rows_out.append(glob_idx[rows[r]])
        cols_out.append(glob_idx[c])
        dist_out.append(dist[r, c])
    return Transitions(src_frame=np.concatenate(rows_out), dst_frame=np.concatenate(cols_out),
                       distance_m=np.concatenate(dist_out))


def _rows(f: WindowFeatures, lo: int, hi: int) -> WindowFeatures:
    return WindowFeatures(f.centres[lo:hi], f.c[lo:hi], f.u[lo:hi], f.v[lo:hi], f.y[lo:hi])


def clip_end_transitions(clips: list[ClipData], window_frames: int, joint_weights: np.ndarray, threshold_m: float,
                         max_per_frame: int, components: np.ndarray) -> Transitions:
    """Transitions that enter each clip's head and leave its tail, for the component step.

    Why: transitions join candidate frames only (contact changes, idle frames), so a clip is entered no earlier
    than its first contact change and left no later than its last; clips that start and end mid-stride lose
    both ends (Bandai dataset 2: 7.5 + 8 frames per clip at the median, 10.8 % of its frames pruned). Here each
    clip's first and last frame whose window fits (h, e) is matched against *every* frame of the other clips
    (not just their candidates): i ~ h gives the edge (i - 1) -> h into the head, e ~ j the edge (e - 1) -> j out
    of the tail. Kept: same contact state, distance below `threshold_m`, a local minimum along the other clip's
    frames, joining two different `components` one of them not the largest; at most `max_per_frame` closest
    per end frame."""
    half = window_frames // 2
    offsets = np.concatenate([[0], np.cumsum([c.n_frames for c in clips])])
    ends, is_head = [], []
    for ci, clip in enumerate(clips):
        first, last = max(half, 1), clip.n_frames - (window_frames - half)
        for frame, head in ((first, True), (last, False)):
            if last >= first:
                ends.append((ci, frame))
                is_head.append(head)
    if not ends:
        empty = np.zeros(0, dtype=np.int64)
        return Transitions(empty, empty, np.zeros(0))
    end_clip = np.array([c for c, _ in ends])
    end_glob = np.array([offsets[c] + f for c, f in ends])
    is_head = np.array(is_head)
    feats = [window_features(clips[c].positions_m, np.array([f]), window_frames, joint_weights) for c, f in ends]
    rows = WindowFeatures(centres=end_glob, c=np.concatenate([f.c for f in feats]),
                          u=np.concatenate([f.u for f in feats]), v=np.concatenate([f.v for f in feats]),
                          y=np.concatenate([f.y for f in feats]))
    end_code = np.array([contact_code(clips[c].contacts[f]) for c, f in ends])
    found_row, found_col, found_d = [], [], []
    for ci, clip in enumerate(clips):
        frames = np.arange(max(half, 1), clip.n_frames - (window_frames - half) + 1)
        if len(frames) == 0:
            continue
        glob = offsets[ci] + frames
        dist = distance_matrix(rows, window_features(clip.positions_m, frames, window_frames, joint_weights))
        masked = np.where((end_code[:, None] == contact_code(clip.contacts[frames])[None, :])
                          & (end_clip[:, None] != ci), dist, np.inf)
        left = np.r_["1", np.full((len(ends), 1), np.inf), masked[:, :-1]]
        right = np.r_["1", masked[:, 1:], np.full((len(ends), 1), np.inf)]
        src = np.where(is_head[:, None], glob[None, :] - 1, end_glob[:, None] - 1)
        dst = np.where(is_head[:, None], end_glob[:, None], glob[None, :])
        a, b = components[src], components[dst]
        keep = (masked < threshold_m) & (masked <= left) & (masked <= right) & (a != b) & ((a != 0) | (b != 0))
        r, c = np.nonzero(keep)
        found_row.append(r)
        found_col.append(glob[c])
        found_d.append(dist[r, c])
    r, col, d = (np.concatenate(x) for x in (found_row, found_col, found_d))
    order = np.lexsort((d, r))  # per end frame, closest first
    r, col, d = r[order], col[order], d[order]
    rank = np.arange(len(r)) - np.searchsorted(r, r)
    sel = rank < max_per_frame if max_per_frame > 0 else np.ones(len(r), dtype=bool)
    r, col, d = r[sel], col[sel], d[sel]
    head = is_head[r]
    return Transitions(src_frame=np.where(head, col, end_glob[r]), dst_frame=np.where(head, end_glob[r], col),
                       distance_m=d)
