"""Held-out clips chained into one long continuous take, as a user's session would be.

Each next clip is turned about +Y and moved on the ground so that its first root ground position equals the
previous clip's last one and its first heading equals the previous clip's last heading: the root path is
continuous (one repeated ground position at each seam), only the limbs jump between the clips' poses. The
take keeps its segments, so sensors can be simulated per clip (no finite-difference spike across a seam) and
the scores can be split by segment.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.errors import CourtsideError
from engine.mocap import Motion, forward_kinematics, quaternions, root_heading


@dataclass
class Segment:
    """One placed clip of a take: frames [start, stop) of the take come from database clip `clip`."""

    clip: int
    label: str
    start: int
    stop: int
    motion: Motion  # placed (turned and moved) copy at the take rate


@dataclass
class Take:
    """A continuous take and its ground truth (world joints, root ground position, heading) at `fps`."""

    segments: list[Segment]
    fps: float
    joints_m: np.ndarray  # (T, J, 3)
    ground_m: np.ndarray  # (T, 2) root joint (x, z)
    heading_rad: np.ndarray  # (T,) from the hips (engine.mocap.root_heading)

    @property
    def n_frames(self) -> int:
        return int(len(self.ground_m))

    @property
    def duration_s(self) -> float:
        return self.n_frames / self.fps

    @property
    def skeleton(self):
        return self.segments[0].motion.skeleton


def yaw_quaternion(angle_rad: float) -> np.ndarray:
    """Rotation about +Y by `angle_rad` (w, x, y, z); adds `angle_rad` to the heading (docs/CONTRACTS.md)."""
    return np.array([np.cos(angle_rad / 2), 0.0, np.sin(angle_rad / 2), 0.0])


def place_motion(motion: Motion, turn_rad: float, pivot_m: np.ndarray, target_ground_m: np.ndarray) -> Motion:
    """The motion turned by `turn_rad` about the vertical through `pivot_m` (3,) and moved so the pivot lands on
    `target_ground_m` (x, z); the height is kept."""
    c, s = np.cos(turn_rad), np.sin(turn_rad)
    rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    root = (motion.root_positions_m - pivot_m) @ rot.T + pivot_m
    root[:, [0, 2]] += np.asarray(target_ground_m, float) - pivot_m[[0, 2]]
    rotations = motion.rotations.copy()
    rotations[:, 0] = quaternions.multiply(yaw_quaternion(turn_rad), rotations[:, 0])
    return Motion(motion.skeleton, motion.fps, root, rotations, motion.name)


def chain_clips(motions: list[Motion], clip_ids: list[int], labels: list[str],
                start_ground_m: np.ndarray = np.zeros(2), start_heading_rad: float = 0.0,
                max_clip_s: float | None = None) -> Take:
    """Chain the given clips (all at one rate, one skeleton) into a take starting at the given root and heading;
    clips longer than `max_clip_s` contribute their first `max_clip_s` seconds."""
    if not clip_ids:
        raise CourtsideError("a take needs at least one clip")
    fps = motions[clip_ids[0]].fps
    segments, joints, heads = [], [], []
    ground, heading, start = np.asarray(start_ground_m, float), float(start_heading_rad), 0
    for ci in clip_ids:
        m = motions[ci]
        if abs(m.fps - fps) > 1e-9:
            raise CourtsideError(f"clip {m.name!r} is at {m.fps:g} Hz, the take at {fps:g} Hz")
        if max_clip_s is not None and m.duration_s > max_clip_s:
            m = m.slice(0, int(round(max_clip_s * fps)))
        pos, _ = forward_kinematics(m)
        h0 = float(root_heading(m, pos[:1])[0])
        placed = place_motion(m, heading - h0, pos[0, 0], ground)
        pos, _ = forward_kinematics(placed)
        head = root_heading(placed, pos)
        segments.append(Segment(ci, labels[ci], start, start + placed.n_frames, placed))
        joints.append(pos)
        heads.append(head)
        ground, heading, start = pos[-1, 0, [0, 2]], float(head[-1]), start + placed.n_frames
    joints_m = np.concatenate(joints)
    return Take(segments, fps, joints_m, joints_m[:, 0, [0, 2]].copy(), np.concatenate(heads))


def plan_chained_takes(labels: list[str], durations_s: list[float], n_takes: int, min_duration_s: float,
                       seed: int = 0, first: str | None = None, max_clip_s: float | None = None) -> list[list[int]]:
    """Clip ids of `n_takes` takes, each ≥ `min_duration_s` (clips counted up to `max_clip_s`), no clip used
    twice, consecutive clips of different contents whenever the data allows (contents visited in a round-robin
    whose order is shuffled per take; `first` opens every take while it has clips)."""
    rng = np.random.default_rng(seed)
    pool: dict[str, list[int]] = {}
    for ci in rng.permutation(len(labels)):
        pool.setdefault(labels[ci], []).append(int(ci))
    takes = []
    for k in range(n_takes):
        order = [c for c in rng.permutation(sorted(pool)) if c != first]
        if first in pool:
            order = [first] + order
        take, total, last = [], 0.0, None
        while total < min_duration_s:
            available = [c for c in order if pool[c] and c != last] or [c for c in order if pool[c]]
            if not available:
                raise CourtsideError(f"not enough held-out clips for {n_takes} takes of {min_duration_s:g} s "
                                     f"(take {k + 1} reached {total:.1f} s); use fewer or shorter takes")
            # the next content after the last one in this take's round-robin order
            content = available[0] if last is None else \
                min(available, key=lambda c: (order.index(c) - order.index(last)) % len(order) or len(order))
            ci = pool[content].pop()
            take.append(ci)
            total += durations_s[ci] if max_clip_s is None else min(durations_s[ci], max_clip_s)
            last = content
        takes.append(take)
    return takes
