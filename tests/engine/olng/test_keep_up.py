"""The live effort control (engine/olng/keep_up.py): steps down when frames cost more than the budget, back up
when they are cheap, and stays at its floor."""
from engine.olng.keep_up import Effort, KeepUp, effort_levels


def test_levels_halve_k_and_i_then_the_iterations_down_to_the_floor() -> None:
    assert effort_levels(Effort(4096, 256, 5)) == [
        Effort(4096, 256, 5), Effort(2048, 128, 5), Effort(1024, 64, 5), Effort(512, 32, 5), Effort(256, 16, 5),
        Effort(256, 16, 2), Effort(256, 16, 1)]
    assert effort_levels(Effort(512, 32, 5), floor=Effort(256, 16, 5)) == [Effort(512, 32, 5), Effort(256, 16, 5)]
    # already below the K / I floor: only the iterations are left to give up
    assert effort_levels(Effort(128, 8, 5)) == [Effort(128, 8, 5), Effort(128, 8, 2), Effort(128, 8, 1)]
    assert effort_levels(Effort(128, 8, 1)) == [Effort(128, 8, 1)]


def test_knowledge_base_size_caps_k_and_i() -> None:
    """The paper's K 4096 / I 256 are for a 500k-frame database; a small one gets a quarter of its frames."""
    from engine.olng.config import NeighbourhoodGraphConfig

    config = NeighbourhoodGraphConfig()
    assert (config.sized_for(633).k_neighbours, config.sized_for(633).i_best) == (128, 16)
    assert (config.sized_for(4000).k_neighbours, config.sized_for(4000).i_best) == (512, 32)
    assert config.sized_for(500_000) == config


def test_steps_down_when_slow_and_back_up_when_fast() -> None:
    keep = KeepUp(effort_levels(Effort(1024, 64, 5)), frame_period_s=0.04, window=10)   # budget 20 ms
    changes = [keep.record(0.030) for _ in range(10)]
    assert changes == [False] * 9 + [True] and keep.effort == Effort(512, 32, 5)
    assert "K 512 / I 32 / 5 it instead of K 1024 / I 64 / 5 it" in keep.status and "30 ms/frame" in keep.status
    # in the gap between budget/3 and budget nothing moves
    assert not any(keep.record(0.012) for _ in range(30)) and keep.level == 1
    assert any([keep.record(0.005) for _ in range(10)]) and keep.level == 0 and keep.status == ""
    # at the floor it stays, however slow
    for _ in range(100):
        keep.record(1.0)
    assert keep.effort == Effort(256, 16, 1)


def test_far_over_budget_it_drops_as_many_levels_as_halvings_after_a_fifth_of_a_window() -> None:
    keep = KeepUp(effort_levels(Effort(4096, 256, 5)), frame_period_s=0.04, window=50)   # budget 20 ms
    changes = [keep.record(0.093) for _ in range(10)]   # 4.65x the budget: log2 -> 3 halvings
    assert changes == [False] * 9 + [True] and keep.effort == Effort(512, 32, 5)
    assert "93 ms/frame" in keep.status
