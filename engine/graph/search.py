"""`ViterbiSearch`: the best path for a whole take, by the search its weights call for.

Seed 000's search (`viterbi.viterbi_search`: every sample stepped, the best final path back-traced) when the
costs never fade; a forgetting search (``SearchWeights.forgetting`` < 1) is decided sample by sample, as the
fixed-lag decoder decides it live (`online.decide_with_forgetting`), so batch and online agree. The choice is made
once, here, above both modules (neither imports the other for it)."""
from __future__ import annotations

from .graph import MotionGraph
from .online import decide_with_forgetting
from .viterbi import (DEFAULT_KERNEL, PRUNE_EVERY, Constraint, Observations, SearchResult, SearchWeights,
                      viterbi_search)
from .warp import RootWarp


class ViterbiSearch:
    """Batch search: the best path for a whole input sequence."""

    def __init__(self, graph: MotionGraph, weights: SearchWeights = SearchWeights(), prune_every: int = PRUNE_EVERY,
                 kernel: str = DEFAULT_KERNEL, warp: RootWarp = RootWarp.off()) -> None:
        self.graph = graph
        self.weights = weights
        self.prune_every = prune_every
        self.kernel = kernel
        self.warp = warp
        self._search = decide_with_forgetting if weights.forgets else viterbi_search

    def run(self, obs: Observations, constraints: list[Constraint] | None = None) -> SearchResult:
        return self._search(self.graph, self.weights, obs, constraints, self.prune_every, self.kernel, self.warp)
