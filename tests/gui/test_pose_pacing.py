"""Pose pacing for the 3-D view: poses decided in bursts are shown one per frame period, in order, none lost;
a large burst (a stall) is skipped down to MAX_BACKLOG so the view never trails far behind."""
from __future__ import annotations

import numpy as np

from engine.stream import FramePose
from gui.pose_pacing import MAX_BACKLOG, PosePacer

RATE_HZ = 30.0


class DecidedPoses:
    """A synthesizer's `recent_poses` over a list that a test appends to (numbered from 1, as the worker does)."""

    def __init__(self) -> None:
        self.poses: list[FramePose] = []

    def decide(self, n: int) -> None:
        for _ in range(n):
            frame = len(self.poses)
            self.poses.append(FramePose(frame, frame / RATE_HZ, np.zeros((2, 3))))

    def recent_poses(self, after: int) -> list[tuple[int, FramePose]]:
        return [(n, p) for n, p in enumerate(self.poses, 1) if n > after]


def run(source: DecidedPoses, pacer: PosePacer, seconds: float, burst_every_s: float, burst: int,
        tick_s: float = 0.01) -> list[tuple[float, int]]:
    """Ticks at `tick_s`; `burst` poses decided every `burst_every_s`: (tick time, frame) of each pose shown."""
    shown, next_burst = [], 0.0
    for now in np.arange(0.0, seconds, tick_s):
        if now >= next_burst - 1e-9:
            source.decide(burst)
            next_burst += burst_every_s
        if pacer.advance(float(now)):
            shown.append((float(now), pacer.current.frame))
    return shown


def test_bursts_of_two_are_shown_one_per_frame_period_in_order_and_none_lost():
    source = DecidedPoses()
    shown = run(source, PosePacer(source, RATE_HZ), seconds=3.0, burst_every_s=2 / RATE_HZ, burst=2)
    frames = [f for _, f in shown]
    assert frames == list(range(len(frames))) and len(frames) >= len(source.poses) - 2
    gaps = np.diff([t for t, _ in shown])
    assert gaps.min() >= 0.75 / RATE_HZ - 1e-9   # never two poses in one frame period's ticks
    assert 28.0 <= len(frames) / 3.0 <= 31.0     # the view moves at the synthesis rate


def test_a_stall_skips_to_at_most_max_backlog_behind():
    source = DecidedPoses()
    pacer = PosePacer(source, RATE_HZ)
    source.decide(20)   # a reconnect delivers 20 decided poses at once
    assert pacer.advance(0.0) and pacer.current.frame == 19 - MAX_BACKLOG
    shown = [pacer.current.frame]
    for now in np.arange(0.01, 0.5, 0.01):
        if pacer.advance(float(now)):
            shown.append(pacer.current.frame)
    assert shown == list(range(19 - MAX_BACKLOG, 20))


def test_reset_forgets_waiting_and_shown_poses():
    source = DecidedPoses()
    pacer = PosePacer(source, RATE_HZ)
    source.decide(3)
    assert pacer.advance(0.0)
    pacer.reset()
    assert pacer.current is None and not pacer.advance(1.0)   # the poses from before the seek are not shown
    source.decide(1)
    assert pacer.advance(2.0) and pacer.current.frame == 3
