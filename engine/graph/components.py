"""Strongly connected components: every node of a search graph should reach every other (Kovar et al. 2002).

A Viterbi path that enters a part of the graph it cannot leave -- the tail of a clip after its last outgoing
transition, a clip with no transitions at all, a few clips that only link to each other -- is trapped there for the
rest of a long take (issue 11: one clip for 50 s; the largest component held 22 % of Bandai dataset 1's nodes).
Two steps fix it:

1. *connect*: while the largest component holds less than `min_component_share` of the frames, add transitions
   at a relaxed threshold, but only ones that join two different components, one of them not the largest, and
   at most `connect_max_per_frame` from one frame (so well-connected clips keep the strict threshold and its
   clean transitions, and a clip group that is strongly connected in itself gets only the few links it
   lacks), trying each of `connect_thresholds_m` in turn;
2. *prune*: keep only the largest component (nodes and the edges between them), as Kovar et al. do.

`ComponentReport` says what each step did; `courtside build-graph` prints it.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components


def component_labels(src: np.ndarray, dst: np.ndarray, n_nodes: int) -> np.ndarray:
    """(N,) strongly connected component of every node of the directed graph src -> dst, numbered by size
    (0 = the largest)."""
    if n_nodes == 0:
        return np.zeros(0, dtype=np.int64)
    adj = csr_matrix((np.ones(len(src), dtype=np.int8), (np.asarray(src), np.asarray(dst))),
                     shape=(n_nodes, n_nodes))
    _, labels = connected_components(adj, directed=True, connection="strong")
    rank = np.empty_like(labels)
    rank[np.argsort(-np.bincount(labels), kind="stable")] = np.arange(labels.max() + 1)
    return rank[labels]


def largest_component(src: np.ndarray, dst: np.ndarray, n_nodes: int) -> np.ndarray:
    """(N,) bool: the nodes of the largest strongly connected component of the directed graph src -> dst."""
    return component_labels(src, dst, n_nodes) == 0


@dataclass
class ComponentReport:
    """What the component step did to one graph (all counts of original database frames unless named)."""

    frames: int = 0  # original frames in the database
    share_before: float = 0.0  # share of frames in the largest component before connecting
    share_connected: float = 0.0  # ... after the relaxed transitions
    relaxed_transitions: int = 0  # transitions added at relaxed thresholds
    thresholds_used_m: tuple[float, ...] = ()
    pruned_nodes: int = 0  # nodes (of every kind) removed by pruning
    pruned_frames: int = 0  # original frames removed by pruning
    pruned_edges: int = 0
    clips_kept: int = 0  # clips with at least one frame left
    clips_total: int = 0

    def as_dict(self) -> dict:
        out = asdict(self)
        out["thresholds_used_m"] = list(self.thresholds_used_m)
        return {k: (round(v, 4) if isinstance(v, float) else v) for k, v in out.items()}
