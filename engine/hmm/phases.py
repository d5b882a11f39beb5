"""Gait-phase segmentation (Mousas 2017 §4.1, Table 1; spec B2.1a).

Eight phases of the right leg's cycle, each entered when its start condition (Table 1) holds; the end condition
of a phase is the start condition of the next, so a plain state machine that only ever advances to the next
phase implements the table. Frames that match no condition extend the current phase. Phases that do not
progress (running has flight phases, jumps have both feet together) are cut into chunks of at most
`max_segment_frames`, keeping their phase label, so every behaviour still yields short segments.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PHASES = ("IC", "LR", "MST", "TST", "PSW", "ISW", "MSW", "TSW")


@dataclass(frozen=True)
class GaitEvents:
    """Per-frame boolean streams: heel/toe contacts of each foot and ankle-crossing events."""

    rh: np.ndarray
    rt: np.ndarray
    lh: np.ndarray
    lt: np.ndarray
    rce: np.ndarray   # right ankle passes the left foot (moving forward)
    lce: np.ndarray   # left ankle passes the right foot


@dataclass(frozen=True)
class Segment:
    start: int      # first frame
    stop: int       # one past the last frame
    phase: int      # index into PHASES


def start_conditions(e: GaitEvents) -> np.ndarray:
    """(F, 8) bool: does frame t satisfy the start condition of phase p (Table 1)."""
    return np.stack([
        e.rh & e.lt,                       # IC
        e.rh & e.rt & ~e.lt,               # LR
        e.rh & e.rt & e.lce,               # MST
        e.rt & ~e.lh & ~e.lt,              # TST
        e.rt & e.lh,                       # PSW
        ~e.rt & e.lh & e.lt,               # ISW
        e.rce & e.lh & e.lt,               # MSW
        ~e.rh & ~e.rt & e.lt,              # TSW
    ], axis=1)


def label_phases(events: GaitEvents) -> np.ndarray:
    """(F,) phase index per frame, -1 before the first frame that matches any start condition."""
    starts = start_conditions(events)
    labels = np.full(len(starts), -1)
    phase = -1
    for t, row in enumerate(starts):
        if phase < 0:
            hits = np.flatnonzero(row)
            phase = int(hits[0]) if len(hits) else -1
        elif row[(phase + 1) % len(PHASES)]:
            phase = (phase + 1) % len(PHASES)
        labels[t] = phase
    return labels


def segments_from_labels(labels: np.ndarray, max_frames: int, min_frames: int) -> list[Segment]:
    """Runs of one phase label, long runs cut into near-equal chunks of at most max_frames; short runs dropped."""
    out = []
    change = np.flatnonzero(np.diff(labels)) + 1
    for s, e in zip(np.r_[0, change], np.r_[change, len(labels)]):
        if labels[s] < 0:
            continue
        pieces = int(np.ceil((e - s) / max_frames))
        cuts = np.linspace(s, e, pieces + 1).round().astype(int)
        out += [Segment(int(a), int(b), int(labels[s])) for a, b in zip(cuts[:-1], cuts[1:]) if b - a >= min_frames]
    return out


def _runs_at_least(flags: np.ndarray, min_len: int) -> np.ndarray:
    out = flags.copy()
    change = np.flatnonzero(np.diff(flags.astype(int))) + 1
    for s, e in zip(np.r_[0, change], np.r_[change, len(flags)]):
        if flags[s] and e - s < min_len:
            out[s:e] = False
    return out


def detect_events(positions_m: np.ndarray, fps: float, joints: dict[str, int], forward: np.ndarray,
                  height_m: float, speed_mps: float, min_frames: int) -> GaitEvents:
    """Events from world joint positions (F, J, 3): contact = low (above each joint's 5th-percentile floor
    level) and slow; crossings = sign changes of the right-minus-left ankle offset along the facing direction.
    joints: indices for 'right_ankle', 'right_toe', 'left_ankle', 'left_toe'; forward: (F, 3) unit facing."""
    def contact(j: int) -> np.ndarray:
        p = positions_m[:, j]
        height = p[:, 1] - np.percentile(p[:, 1], 5.0)
        speed = np.linalg.norm(np.gradient(p, axis=0), axis=1) * fps
        return _runs_at_least((height < height_m) & (speed < speed_mps), min_frames)

    ahead = np.einsum("fk,fk->f", positions_m[:, joints["right_ankle"]] - positions_m[:, joints["left_ankle"]], forward)
    sign = np.sign(ahead)
    rce = np.r_[False, (sign[:-1] < 0) & (sign[1:] >= 0)]
    lce = np.r_[False, (sign[:-1] > 0) & (sign[1:] <= 0)]
    return GaitEvents(rh=contact(joints["right_ankle"]), rt=contact(joints["right_toe"]),
                      lh=contact(joints["left_ankle"]), lt=contact(joints["left_toe"]), rce=rce, lce=lce)
