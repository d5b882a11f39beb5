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
    cluster_proximity: metres of pair-distance std added per metre of mean pair distance before clustering.
        Why: when a segment barely moves during training, its markers are as "rigid" with the far side of the
        body as with their neighbours, and the clusters come out anatomically absurd (head + right upper arm on
        CMU 135_02), which later locks bodies into swaps. The term makes near markers the tie-break: 0.3 m
        apart costs 6 mm, less than a moving joint adds.
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
    shape_reacquire: after the gated passes, look for each body's missing markers among the leftover points by
        the body's shape alone (reacquire.py), wherever the filters predict them. Issue 14: without it a body
        lost on a long take is predicted forever.
    shape_min_support: mean link term a point needs with the body's other markers to be re-acquired by shape.
    shape_sigma_min_m: floor on A when matching by shape (skin markers stretch more than a short window shows).
    neighbour_std_m, max_neighbours, neighbour_sigma_min_m: each marker's (up to max_neighbours) steadiest links
        to markers of its subject's other bodies (training std ≤ neighbour_std_m: across one joint) join the
        Eq. 5 score of the second-chance pass and check shape re-acquisition, with A floored at
        neighbour_sigma_min_m. Why: bodies of identical shape (left and right hand)
        score the same on their own links, and on CMU 135_02 the hands swapped for good when they met; a link to
        the elbow tells them apart. neighbour_min_support: a marker re-acquired by shape is dropped when its mean
        neighbour link term is below this (≈ 3 sigmas off: a quiet training window understates how far a joint
        stretches, so only a clear contradiction, the other hand, is refused).
    motion_weight: weight (in links) of each marker's agreement with its Kalman prediction in the body score;
        it breaks ties between body-mates' points (see OnlineLabeler._prior). 0 = the paper's gate-only use.
    repair_swaps, repair_min_rms_m, repair_tol_scale, repair_ratio: undo swaps inside a body by its training
        template (see OnlineLabeler._repair_swaps); a body whose rigid-fit RMS is below repair_min_rms_m and below
        repair_tol_scale x its training 95th percentile is left alone, and a relabelling is kept only if its RMS
        is below repair_ratio x the current one.
    max_recovered_s: a marker recovered from its body for longer than this counts as lost (its position is no
        longer reported nor fed to its Kalman filter): a rigid-body guess drifts as the skin and the body move.
    reentry_max_age_s, reentry_turn_rad, reentry_settled_rad: a body coming back after a loss, complete at most
        reentry_max_age_s ago, is relabelled to a shape twin of its labels when the current labels imply it
        turned by more than reentry_turn_rad and the twin by less than reentry_settled_rad (see
        OnlineLabeler._orient_reentering_bodies: mirrored heads after a forced loss).
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
    cluster_proximity: float = 0.02
    min_body: int = 3
    max_body: int = 8
    window_frames: int = 50
    recovery: str = "kabsch"
    min_observed_for_recovery: int = 1
    recovered_noise_scale: float = 25.0
    max_combinations: int = 20000
    reacquire_gate_scale: float = 25.0
    reacquire_min_support: float = 0.1
    shape_reacquire: bool = True
    shape_min_support: float = 0.5
    shape_sigma_min_m: float = 0.004
    neighbour_std_m: float = 0.03
    max_neighbours: int = 3
    neighbour_sigma_min_m: float = 0.015
    neighbour_min_support: float = 0.01
    motion_weight: float = 0.3
    repair_swaps: bool = True
    repair_min_rms_m: float = 0.004
    repair_tol_scale: float = 2.0
    repair_ratio: float = 0.5
    max_recovered_s: float = 0.5
    reentry_max_age_s: float = 1.0
    reentry_turn_rad: float = 2.0944  # 120°
    reentry_settled_rad: float = 1.0472  # 60°

    def __post_init__(self) -> None:
        if self.recovery not in ("offsets", "kabsch"):
            raise ValueError(f"recovery must be 'offsets' or 'kabsch', got {self.recovery!r}")
        if not 2 <= self.min_body <= self.max_body:
            raise ValueError(f"need 2 <= min_body <= max_body, got {self.min_body}, {self.max_body}")
        if self.train_frames < 3 or self.window_frames < 2 or self.max_candidates < 1:
            raise ValueError("train_frames >= 3, window_frames >= 2 and max_candidates >= 1 are required")
