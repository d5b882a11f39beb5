"""Every tunable constant of the single-IMU hierarchical HMM (Mousas 2017; spec B2), with the spec's defaults."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class HMMConfig:
    fps: float = 30.0                 # paper: both streams downsampled to 30 fps
    imu_channels: str = "acc+gyro"    # paper: acc + gyro per IMU. "acc": accelerometer only (a stream without
                                      # gyroscope); "+tilt": also each IMU's up vector in its own axes from its
                                      # orientation quaternion (yaw-free, issue 18): "acc+tilt", "acc+gyro+tilt"
    # segmentation (B2.1a)
    contact_height_m: float = 0.05    # heel/toe touching: below this height above its floor level ...
    contact_speed_mps: float = 0.6    # ... and slower than this (spec: 0.3; CMU heels still move 0.3-0.5 m/s at contact)
    contact_min_frames: int = 2       # hysteresis: shorter contact runs are dropped
    max_segment_frames: int = 12      # phases that do not progress (runs, jumps) are cut into chunks this long
    min_segment_frames: int = 2
    medoid_candidates: int = 10       # reference = DTW medoid among at most this many segments of a phase
    # Gaussians (B2.3)
    ridge: float = 1e-2               # Sigma_YY += ridge * diag(var) ...
    ridge_floor: float = 1.0          # ... + floor I (z units). Spec: 1e-3; with H < dim(Y) samples per frame that
                                      # let the gain explode (CMU leave-one-out: 10.7 vs 5.3 cm, docs)
    sigma: float = 0.5                # recognition emission sd in z-units
    # transitions: self / next / skip inside a chain, self / next / exit at chain end, all 1/3 (B2.3)
    p_self: float = 1.0 / 3.0
    p_next: float = 1.0 / 3.0
    p_skip: float = 1.0 / 3.0
    # runtime (B2.4-B2.5)
    forward_mode: str = "window"      # "window": forward over the last W frames from a uniform start (paper);
                                      # "recursive": one step per frame, alpha mixed with uniform by epsilon
    window: int = 20
    epsilon: float = 1e-6             # recursive mode: floor that lets a wrong hypothesis recover
    k_interpolate: int = 4            # K segment models interpolated
    output: str = "posterior"         # "posterior": alpha-weighted conditional mean (Eq. 13); "argmax": best state
    blend_frames: int = 6             # inertialisation after a phase switch
