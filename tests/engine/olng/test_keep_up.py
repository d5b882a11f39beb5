"""The live effort control (engine/olng/keep_up.py): steps down when frames cost more than the budget, back up
when they are cheap, and stays at its floor."""
import numpy as np

from engine.olng.keep_up import Effort, KeepUp, effort_levels


def test_levels_halve_down_to_the_floor() -> None:
    assert effort_levels(4096, 256) == [Effort(4096, 256), Effort(2048, 128), Effort(1024, 64), Effort(512, 32),
                                        Effort(256, 16)]
    assert effort_levels(512, 32, floor=Effort(256, 16)) == [Effort(512, 32), Effort(256, 16)]
    assert effort_levels(128, 8) == [Effort(128, 8)]   # already below the floor: nothing cheaper to offer


def test_steps_down_when_slow_and_back_up_when_fast() -> None:
    keep = KeepUp(effort_levels(1024, 64), frame_period_s=0.04, window=10)   # budget 20 ms
    changes = [keep.record(0.030) for _ in range(10)]
    assert changes == [False] * 9 + [True] and keep.effort == Effort(512, 32)
    assert "K 512 / I 32 instead of K 1024 / I 64" in keep.status and "30 ms/frame" in keep.status
    # in the gap between budget/3 and budget nothing moves
    assert not any(keep.record(0.012) for _ in range(30)) and keep.level == 1
    assert any([keep.record(0.005) for _ in range(10)]) and keep.level == 0 and keep.status == ""
    # at the floor it stays, however slow
    for _ in range(100):
        keep.record(1.0)
    assert keep.effort == Effort(256, 16)


def test_far_over_budget_it_drops_as_many_levels_as_halvings_after_a_fifth_of_a_window() -> None:
    keep = KeepUp(effort_levels(4096, 256), frame_period_s=0.04, window=50)   # budget 20 ms
    changes = [keep.record(0.093) for _ in range(10)]   # 4.65x the budget: log2 -> 3 halvings
    assert changes == [False] * 9 + [True] and keep.effort == Effort(512, 32)
    assert "93 ms/frame" in keep.status
