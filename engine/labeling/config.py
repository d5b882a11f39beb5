"""Every tunable constant of the online labeler (paper 001), in SI units, with the spec's recommended defaults."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class LabelingConfig:
    """Constants of training, gating, fitting, recovery and model updates.

    Lengths are metres, accelerations m/s². Defaults follow spec 001 §2 and §6 where it recommends a value.

    train_frames: labelled frames used to learn the structure model, with subjects apart (paper: 50).
    meas_noise_m: measurement noise r of each marker (R = r² I).
    accel_std_floor_mps2: floor on each marker's process-noise acceleration std (q_k = max(var(a), floor²)), so a
        marker that stood still in training still gets a usable gate; a tennis wrist needs far more than a heel.
    accel_std_scale: multiplier on the training acceleration std (training rarely contains the fastest moves).
    gate_chi2: squared Mahalanobis gate γ (χ²₃(0.99) = 11.34).
    max_candidates: K, candidates kept per label (nearest first).
    sigma_min_m: floor on the pair-distance std A (rigid synthetic bodies have A = 0).
    cluster_tau_m: complete-linkage threshold on A for rigid-body clustering (largest std inside a body).
    cluster_tau_max_m: if larger than cluster_tau_m, τ_A is searched on a geometric grid from cluster_tau_m to
        this value for the one putting most markers into bodies of min_body..max_body (spec §2.2 option).
    min_body, max_body: rigid-body size range (paper: 3-8 markers).
    window_frames: T, sliding-window length of the distance statistics (paper gives none; spec: 50).
    recovery: "kabsch" (rigid fit of the body's last complete configuration; the spec's flagged deviation that
        removes rotation drift — default because on the real tennis data it cuts the recovery error 3x and lifts
        accuracy from 0.94 to 0.98) or "offsets" (paper §3.3: mean of observed marker + last world offset).
    min_observed_for_recovery: observed markers a body needs before a missing one is recovered (else "lost").
    recovered_noise_scale: the Kalman filter takes a recovered position with R scaled by this (spec: 25).
        A label that is neither observed nor recovered ("lost") has its velocity zeroed: extrapolating a fast
        wrist for many frames sends its gate far from the body, while a held position plus the gate growing
        with P lets the body search pick it up again.
    max_combinations: cap on one body's exhaustive search; beyond it the farthest candidates are dropped.
    reacquire_gate_scale: γ multiplier for the second-chance pass that offers missing labels the points no
        body took (see OnlineLabeler._second_chance; 25 = five times the gate radius).
    reacquire_min_support: a point re-acquired that way must have a mean Eq. 5 link term of at least this with
        its body's other assigned markers (guards the wide gate against ghosts and the other subject's points).
    """

    train_frames: int = 50
    meas_noise_m: float = 0.001
    accel_std_floor_mps2: float = 20.0
    accel_std_scale: float = 2.0
    gate_chi2: float = 11.34
    max_candidates: int = 4
    sigma_min_m: float = 0.001
    cluster_tau_m: float = 0.003
    cluster_tau_max_m: float = 0.03
    min_body: int = 3
    max_body: int = 8
    window_frames: int = 50
    recovery: str = "kabsch"
    min_observed_for_recovery: int = 1
    recovered_noise_scale: float = 25.0
    max_combinations: int = 20000
    reacquire_gate_scale: float = 25.0
    reacquire_min_support: float = 0.1

    def __post_init__(self) -> None:
        if self.recovery not in ("offsets", "kabsch"):
            raise ValueError(f"recovery must be 'offsets' or 'kabsch', got {self.recovery!r}")
        if not 2 <= self.min_body <= self.max_body:
            raise ValueError(f"need 2 <= min_body <= max_body, got {self.min_body}, {self.max_body}")
        if self.train_frames < 3 or self.window_frames < 2 or self.max_candidates < 1:
            raise ValueError("train_frames >= 3, window_frames >= 2 and max_candidates >= 1 are required")
