"""The per-clip arrays the graph is built from, independent of how they were read.

Keeping the builder on plain arrays lets it be tested on synthetic clips with exact answers; `from_motion`
(engine.graph.mocap_adapter) fills the same structure from an engine.mocap Motion.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ClipData:
    """One database clip at the graph rate.

    Shapes: F frames, J joints, S sensors. Positions are in the clip's own world frame (Y up, metres).
    `acc_g[f]` is the virtual acceleration at frame f (what the sensors read on arriving at f).
    Optional MSV streams: `acc_slow_g` (2F-1, S, 3) = the clip played at half speed sampled every half frame
    (even rows are the original frames), `acc_fast_g` (F, S, 3) = the clip played at double speed, read at each
    original frame (row f is the reading on arriving at f after skipping f-1).
    Optional `local_rotations` (F, J, 4) (w, x, y, z) + `root_positions_m` (F, 3) let the synthesis write a BVH.
    """

    name: str
    positions_m: np.ndarray  # (F, J, 3)
    contacts: np.ndarray  # (F, 2) bool, [left, right]
    heading_rad: np.ndarray  # (F,)
    acc_g: np.ndarray  # (F, S, 3)
    label: str = ""
    acc_slow_g: np.ndarray | None = None
    acc_fast_g: np.ndarray | None = None
    local_rotations: np.ndarray | None = None
    root_positions_m: np.ndarray | None = None
    root_joint: int = 0

    def __post_init__(self) -> None:
        f = self.positions_m.shape[0]
        checks = {
            "positions_m": (self.positions_m.ndim == 3 and self.positions_m.shape[2] == 3),
            "contacts": self.contacts.shape == (f, 2),
            "heading_rad": self.heading_rad.shape == (f,),
            "acc_g": self.acc_g.ndim == 3 and self.acc_g.shape[0] == f and self.acc_g.shape[2] == 3,
        }
        if self.acc_slow_g is not None:
            checks["acc_slow_g"] = self.acc_slow_g.shape == (2 * f - 1,) + self.acc_g.shape[1:]
        if self.acc_fast_g is not None:
            checks["acc_fast_g"] = self.acc_fast_g.shape == self.acc_g.shape
        if self.local_rotations is not None:
            checks["local_rotations"] = self.local_rotations.shape == (f, self.positions_m.shape[1], 4)
            checks["root_positions_m"] = self.root_positions_m is not None and self.root_positions_m.shape == (f, 3)
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise ValueError(f"clip {self.name!r}: inconsistent array shapes for {', '.join(bad)}")
        self.contacts = self.contacts.astype(bool)

    @property
    def n_frames(self) -> int:
        return int(self.positions_m.shape[0])

    @property
    def ground_m(self) -> np.ndarray:
        """(F, 2) ground-plane (x, z) position of the root joint."""
        return self.positions_m[:, self.root_joint, [0, 2]]
