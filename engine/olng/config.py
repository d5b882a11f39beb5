"""Every tunable constant of the OLNG reconstructor (Tautges et al. 2011), with the spec's defaults.

WHY dataclasses: the paper leaves most constants open (window length, step rules, penalties), so each one is a
named, documented knob that benches and tests can sweep instead of a literal buried in the code.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace


@dataclass(frozen=True)
class NeighbourhoodGraphConfig:
    """Online lazy neighbourhood graph and kNN search (spec A2.3-A2.5)."""

    k_neighbours: int = 4096      # K: nearest database frames per input frame (paper: 4096)
    window: int = 32              # M: columns kept; an upper bound on match length (spec default 32)
    max_column_step: int = 2      # dc_max: 2 = at most one skipped input column
    max_warp: int = 2             # database index may advance at most max_warp * dc per step
    skip_cost: str = "held"       # skipped column priced as "held" (distance to the predecessor's frame) or "miss" (mu, spec)
    skip_penalty: float = 1.0     # multiplier on that skip cost
    i_best: int = 256             # I: paths that become hypotheses for the energy (paper: 256)
    leafsize: int = 32            # cKDTree leaf size
    tilt_weight: float = 1.0      # orientation channel: weight of each sensor's up vector (g-equivalent; 1 = the
                                  # gravity part of an acc reading), engine/olng/channels.py
    gyro_weight_s: float = 0.1    # gyro channel: rad/s -> g-equivalent (5 rad/s weighs like 0.5 g)
    yaw_weight: float = 1.5       # orientation channel: weight of each sensor's yaw relative to sensor 0 (chord
                                  # length, <= 2), once its device offset is estimated (engine/olng/yaw.py); 0 = off;
                                  # swept 0.5-3 (docs)
    yaw_min_frames: int = 10      # frames of offset samples before the yaw term may act (0.4 s at 25 Hz; 50 left
                                  # half of a 4 s gesture clip without it)

    def sized_for(self, n_frames: int) -> NeighbourhoodGraphConfig:
        """K and I for a knowledge base of ``n_frames``: K at most the largest power of two within a quarter of
        the database (at least 64), I at most K / 16 (at least 16). WHY: the paper's K 4096 / I 256 belong to a
        500k-frame database; on the shipped clips (633 frames) K 4096 takes every frame as a neighbour and the
        hypotheses blur. Leave-one-out over the 9 shipped clips, joint cm acc / acc+orientation+gyro: K 4096 /
        I 256 7.75 / 7.02, K 512 / I 32 4.56 / 4.18, K 256 / I 16 4.25 / 3.83, K 128 / I 16 4.11 / 3.78, K 64 /
        I 4 4.05 / 4.05 (docs/engine-olng-hmm.md). A database of 16k frames or more keeps the configured values."""
        k_cap = max(64, 1 << max(0, int(n_frames // 4).bit_length() - 1))
        k = min(self.k_neighbours, k_cap)
        return replace(self, k_neighbours=k, i_best=min(self.i_best, max(16, k // 16)))


@dataclass(frozen=True)
class EnergyConfig:
    """Kernel-prior energy (spec A2.6-A2.8); the w_* weights are the paper's."""

    w_prior: float = 5.0
    w_control: float = 1.0
    w_pose: float = 0.6
    w_motion: float = 0.2
    w_smooth: float = 0.2
    w_tilt: float = 10.0                 # orientation channel (issue 18, not in the paper): each sensor's measured tilt
                                         # against the tilt the pose gives it (engine/olng/energy.py); swept 0-30 on
                                         # Bandai gestures + CMU walks (docs/engine-olng-hmm.md): 10 best overall
    tilt_lever_m: float = 0.25           # a unit tilt difference weighs like this position error (a forearm's length:
                                         # a small tilt error of a rad moves its far end about that much)
    epsilon: float = 1e-3                # pseudo-Huber floor inside sqrt(|r|): sqrt has infinite slope at 0
    variance_kept: float = 0.99          # weighted-PCA subspace keeps this fraction of the weighted variance
    min_components: int = 3              # guard when all weight sits on one pose
    solver: str = "auto"                 # "auto": majorise-minimise (sqrt kernel) / Levenberg-Marquardt (Mahalanobis);
                                         # "trf": scipy least_squares as the spec suggests (slow: SVD per iteration)
    max_iterations: int = 5              # iterations per frame ("converges after few iterations"; 3, 5 and 10 gave
                                         # the same CMU leave-one-out error to 0.01 cm)
    max_nfev: int = 30                   # least_squares budget per frame (solver="trf")
    length_unit_m: float = 0.01          # unit of positions inside the energy (0.01 = cm, spec A2.8)
    angle_unit_rad: float = math.pi / 180  # unit of angles inside the energy: degrees. The spec suggests rad; on
                                         # CMU leave-one-out rad made the pose prior too weak (7.3 vs 5.5 cm, docs)
    kernel: str = "sqrt"                 # "sqrt" (paper) or "mahalanobis" (Fig. 11 baseline b)
    control_reading: str = "previous"    # "previous": alpha^t drives E_contr as in the paper; "current": alpha^{t+1}


@dataclass(frozen=True)
class KnowledgeBaseConfig:
    """How the database is prepared (spec A2.1)."""

    fps: float = 25.0          # the paper's knowledge base rate
    mirror: bool = False       # "M": add left/right mirrored copies
    reverse: bool = False      # "R": add time-reversed copies


@dataclass(frozen=True)
class OLNGConfig:
    """Everything the streaming reconstructor needs."""

    graph: NeighbourhoodGraphConfig = field(default_factory=NeighbourhoodGraphConfig)
    energy: EnergyConfig = field(default_factory=EnergyConfig)
    knowledge_base: KnowledgeBaseConfig = field(default_factory=KnowledgeBaseConfig)
