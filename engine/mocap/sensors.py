"""Virtual body-worn sensors: accelerometers (g) and gyroscopes (rad/s) simulated from mocap, plus a
sensor-error model that makes them look like real hardware.

A sensor is rigidly attached to one joint's segment (`SensorPlacement`): a point `offset_m` and an
orientation `rotation` (sensor axes -> joint frame), both in that joint's frame. Readings:

    acc_g(t)  = R_s(t)^T (p''(t) - g_world) / 9.80665,   g_world = (0, -9.80665, 0)
    gyro(t)   = log(R_s(t-1)^T R_s(t+1)) / (2 dt)        (body-frame angular rate)

p'' is the central second difference of the sensor point's world position (first/last frame copy their
neighbour's reading). So a sensor at rest reads +1 g along world up, as a real MEMS accelerometer does.

Standard placements (`standard_placements`) follow the seeds: forearms, shins, lower back, chest (seed 000),
wrists and ankles at 87.5 % of the forearm/shin (seed 003, X along the bone distally, arms Z up in the
T-pose, legs Z forward, Y = Z x X) and the right foot (seed 004). Offsets and frames are defined on the
skeleton's T-pose (engine.mocap.rest_pose: same bones, frames re-based so the zero pose is a T-pose facing
+Z) and mapped back into the file's joint frames, so they are anatomical for CMU ASF and CMU BVH (whose
zero pose is not a T-pose); on Bandai the right limbs and feet keep a fixed roll from the file's frame
convention (see rest_pose.tpose_bases)."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from engine.mocap import quaternions as quat
from engine.mocap.rest_pose import tpose_bases, tpose_skeleton
from engine.mocap.roles import joint_roles
from engine.mocap.skeleton import Motion, Skeleton, forward_kinematics

GRAVITY_MPS2 = 9.80665
G_WORLD = np.array([0.0, -GRAVITY_MPS2, 0.0])
UP = np.array([0.0, 1.0, 0.0])
SEED000_NOISE_G = 0.709  # solved by engine.mocap.bench.calibrate_seed000_noise; see SensorErrorModel.seed000
REAL_GAP_G2 = 0.15  # real-vs-virtual gap measured on 50 s of six Xsens IMUs against their best calibration (issue 11)
REAL_NOISE_REL = 0.212  # solved by engine.mocap.bench.calibrate_real_noise (then one secant step) for REAL_GAP_G2


@dataclass(frozen=True, eq=False)
class SensorPlacement:
    """One worn sensor: on `joint`'s segment at `offset_m` (joint frame), axes `rotation` (sensor -> joint),
    and an optional constant accelerometer offset `bias_g` (3,) g added to its virtual readings (a calibrated
    real sensor's bias; None = no bias). `engine.mocap.calibrated` fills rotation/bias from a calibration."""

    name: str
    joint: int
    offset_m: np.ndarray
    rotation: np.ndarray
    bias_g: np.ndarray | None = None

    def __post_init__(self) -> None:
        rot = np.asarray(self.rotation, float)
        if rot.shape != (3, 3) or not np.allclose(rot @ rot.T, np.eye(3), atol=1e-6) or np.linalg.det(rot) < 0:
            raise ValueError(f"sensor {self.name!r}: rotation must be a proper 3x3 rotation matrix")
        object.__setattr__(self, "offset_m", np.asarray(self.offset_m, float).reshape(3))
        object.__setattr__(self, "rotation", rot)
        if self.bias_g is not None:
            object.__setattr__(self, "bias_g", np.asarray(self.bias_g, float).reshape(3))


# name -> (segment role, distal role, fraction of the bone, frame kind)
_STANDARD = {
    "left_forearm": ("left_elbow", "left_wrist", 0.5, "arm"),
    "right_forearm": ("right_elbow", "right_wrist", 0.5, "arm"),
    "left_shin": ("left_knee", "left_ankle", 0.5, "leg"),
    "right_shin": ("right_knee", "right_ankle", 0.5, "leg"),
    "left_wrist": ("left_elbow", "left_wrist", 0.875, "arm"),
    "right_wrist": ("right_elbow", "right_wrist", 0.875, "arm"),
    "left_ankle": ("left_knee", "left_ankle", 0.875, "leg"),
    "right_ankle": ("right_knee", "right_ankle", 0.875, "leg"),
    "right_foot": ("right_ankle", "right_toe", 0.5, "foot"),
    "lower_back": ("pelvis", None, 0.0, "back"),
    "chest": ("upper_back", None, 0.0, "chest"),
}
SEED000_SENSORS = ("left_forearm", "right_forearm", "left_shin", "right_shin", "lower_back", "chest")
SEED003_SENSORS = ("left_wrist", "right_wrist", "left_ankle", "right_ankle")
SEED004_SENSORS = ("right_foot",)
STANDARD_SENSORS = tuple(_STANDARD)
TRUNK_DEPTH_M = 0.10  # a back/chest sensor sits this far behind/in front of the spine joint


def _frame(x_axis: np.ndarray, z_hint: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Columns X, Y, Z with X along x_axis, Z the part of z_hint orthogonal to X, Y = Z x X."""
    x = x_axis / np.linalg.norm(x_axis)
    hint = z_hint if abs(x @ z_hint) < 0.9 * np.linalg.norm(z_hint) else fallback
    z = hint - (hint @ x) * x
    z /= np.linalg.norm(z)
    return np.column_stack([x, np.cross(z, x), z])


def standard_placements(skeleton: Skeleton, names: tuple[str, ...] | list[str] = SEED000_SENSORS) -> list[SensorPlacement]:
    """Placements for the named standard sensors (see STANDARD_SENSORS) on this skeleton.

    Depends on the skeleton only, so every clip of one skeleton gets identical placements (see
    rest_pose.tpose_bases for the one caveat: sensor roll on some Bandai segments)."""
    unknown = [n for n in names if n not in _STANDARD]
    if unknown:
        raise ValueError(f"unknown sensor name(s) {unknown}; known: {', '.join(STANDARD_SENSORS)}")
    roles = joint_roles(skeleton)
    bases = tpose_bases(skeleton)  # define every sensor on the T-pose, then map into the file's joint frames
    rest = tpose_skeleton(skeleton, bases).rest_positions()
    fwd = np.array([0.0, 0.0, 1.0])
    left = np.cross(UP, fwd)
    out = []
    for name in names:
        seg_role, distal_role, fraction, kind = _STANDARD[name]
        joint = roles[seg_role]
        outward = left if name.startswith("left") else -left
        if distal_role is not None:
            bone = rest[roles[distal_role]] - rest[joint]
            offset = fraction * bone
            z_hint = {"arm": UP, "leg": fwd, "foot": UP}[kind]
            rotation = _frame(bone, z_hint, outward if kind == "arm" else fwd)
        else:
            depth = -TRUNK_DEPTH_M if kind == "back" else TRUNK_DEPTH_M
            offset = depth * fwd
            rotation = _frame(UP, np.sign(depth) * fwd, outward)
        out.append(SensorPlacement(name, joint, bases[joint] @ offset, bases[joint] @ rotation))
    return out


def _sensor_world(motion: Motion, placements: list[SensorPlacement],
                  fk: tuple[np.ndarray, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray]:
    """World positions (F, S, 3) and orientations (F, S, 3, 3) of the sensors."""
    pos, glob = forward_kinematics(motion) if fk is None else fk
    joints = np.array([p.joint for p in placements], int)
    offsets = np.stack([p.offset_m for p in placements])
    rots = np.stack([p.rotation for p in placements])
    g = glob[:, joints]  # (F, S, 3, 3)
    return pos[:, joints] + np.einsum("fsij,sj->fsi", g, offsets), g @ rots


def virtual_accelerometers(motion: Motion, placements: list[SensorPlacement], clip_g: float | None = None,
                           fk: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """(F, S, 3) specific force in g in each sensor's frame (plus each placement's `bias_g`, if set);
    optionally saturate at +-clip_g.

    The first and last frames have no central difference; they repeat their neighbour's *reading*."""
    p, r = _sensor_world(motion, placements, fk)
    if len(p) < 3:
        raise ValueError("need at least 3 frames for finite-difference acceleration")
    acc = np.empty(p.shape)
    specific = (p[2:] - 2 * p[1:-1] + p[:-2]) * motion.fps**2 - G_WORLD
    acc[1:-1] = np.einsum("fsji,fsj->fsi", r[1:-1], specific) / GRAVITY_MPS2
    acc[0], acc[-1] = acc[1], acc[-2]
    if any(p.bias_g is not None for p in placements):
        acc += np.stack([np.zeros(3) if p.bias_g is None else p.bias_g for p in placements])
    return np.clip(acc, -clip_g, clip_g) if clip_g is not None else acc


def virtual_gyroscopes(motion: Motion, placements: list[SensorPlacement],
                       fk: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """(F, S, 3) angular rate in rad/s in each sensor's frame (central difference of orientation)."""
    _, r = _sensor_world(motion, placements, fk)
    if len(r) < 3:
        raise ValueError("need at least 3 frames for finite-difference angular rate")
    rel = np.swapaxes(r[:-2], -1, -2) @ r[2:]
    gyro = np.empty(r.shape[:-1])
    gyro[1:-1] = quat.log_matrix(rel) * (motion.fps / 2.0)
    gyro[0], gyro[-1] = gyro[1], gyro[-2]
    return gyro


@dataclass(frozen=True)
class SensorErrorModel:
    """Real-sensor imperfections applied to clean virtual readings (all per sensor, all optional).

    noise_g: white noise sd per axis; bias_g: constant offset sd per axis; scale_error: sd of the per-axis
    gain error (0.02 = 2 %); misalignment_rad: sd of the angle of a fixed random rotation (mounting error /
    placement slip); jitter_s: sd of per-sample timing error (readings resampled at t + jitter);
    saturation_g: full-scale range (readings clip at +-saturation_g, ±12 g in the seed-000 hardware);
    noise_rel: noise that scales with the signal -- per sample and axis, sd = noise_rel x the magnitude of the
    reading's dynamic part |a_t - mean_s(a)| (soft tissue and strap wobble, a lever arm off the bone: the faster
    the segment moves, the further a real sensor's reading strays from the virtual one; a sensor at rest reads
    nearly what the model predicts); sensor_scale: per-sensor factor on both noise terms (a wrist strap moves
    more than a chest belt), one value per sensor column, None = all 1."""

    noise_g: float = 0.0
    bias_g: float = 0.0
    scale_error: float = 0.0
    misalignment_rad: float = 0.0
    jitter_s: float = 0.0
    saturation_g: float | None = 12.0
    noise_rel: float = 0.0
    sensor_scale: tuple[float, ...] | None = None

    @classmethod
    def measured_real(cls) -> "SensorErrorModel":
        """Preset for a calibrated real body-worn IMU: small systematic terms (bias 0.03 g, gain 2 %, mounting
        3°, timing 2 ms), a small noise floor (0.02 g) and noise proportional to the motion (`noise_rel`,
        solved so the mean gap is REAL_GAP_G2 = 0.15 g² on the shipped CMU clips at 30 Hz, as measured on a real
        recording -- a tenth of seed000's 1.6 g², and concentrated where the body moves fast)."""
        return cls(noise_g=0.02, bias_g=0.03, scale_error=0.02, misalignment_rad=np.radians(3.0), jitter_s=0.002,
                   saturation_g=16.0, noise_rel=REAL_NOISE_REL)

    @classmethod
    def seed000(cls) -> "SensorErrorModel":
        """Preset whose real-vs-virtual gap matches seed 000 (1.6 g² mean squared error per sensor vector).

        The systematic terms are plausible hardware values; `noise_g` was then solved so the mean over all
        frames and sensors of ||perturbed - clean||² is 1.6 g² on the shipped CMU clips at 30 Hz with the six
        seed-000 sensors (`python -m engine.mocap.bench` re-measures it; a test checks it stays within 10 %)."""
        return cls(noise_g=SEED000_NOISE_G, bias_g=0.1, scale_error=0.05, misalignment_rad=np.radians(10.0),
                   jitter_s=0.005, saturation_g=12.0)

    def with_noise(self, noise_g: float) -> "SensorErrorModel":
        return replace(self, noise_g=noise_g)

    def apply(self, acc_g: np.ndarray, fps: float, rng: np.random.Generator) -> np.ndarray:
        """Perturbed copy of clean readings (F, S, 3); deterministic for a given rng state."""
        acc = np.asarray(acc_g, float)
        n_frames, n_sensors, _ = acc.shape
        out = acc
        if self.jitter_s > 0 and n_frames > 1:
            t = np.arange(n_frames) / fps
            shifted = np.clip(t[:, None] + rng.normal(0.0, self.jitter_s, (n_frames, n_sensors)), 0, t[-1])
            out = np.stack([np.stack([np.interp(shifted[:, s], t, acc[:, s, k]) for k in range(3)], axis=-1)
                            for s in range(n_sensors)], axis=1)
        if self.misalignment_rad > 0:
            axes = rng.normal(size=(n_sensors, 3))
            axes /= np.linalg.norm(axes, axis=1, keepdims=True)
            angles = rng.normal(0.0, self.misalignment_rad, n_sensors)
            slip = quat.to_matrix(quat.from_rotvec(axes * angles[:, None]))  # (S, 3, 3)
            out = np.einsum("sij,fsj->fsi", slip, out)
        if self.scale_error > 0:
            out = out * (1.0 + rng.normal(0.0, self.scale_error, (n_sensors, 3)))
        if self.bias_g > 0:
            out = out + rng.normal(0.0, self.bias_g, (n_sensors, 3))
        if self.noise_g > 0 or self.noise_rel > 0:
            sd = np.full(out.shape[:2], self.noise_g)
            if self.noise_rel > 0:
                sd = sd + self.noise_rel * np.linalg.norm(acc - acc.mean(axis=0), axis=-1)
            if self.sensor_scale is not None:
                if len(self.sensor_scale) != n_sensors:
                    raise ValueError(f"sensor_scale has {len(self.sensor_scale)} values for {n_sensors} sensors")
                sd = sd * np.asarray(self.sensor_scale, float)
            out = out + rng.normal(0.0, 1.0, out.shape) * sd[..., None]
        if self.saturation_g is not None:
            out = np.clip(out, -self.saturation_g, self.saturation_g)
        return out


def mean_squared_error_g2(a_g: np.ndarray, b_g: np.ndarray) -> float:
    """Seed-000 accelerometer error: mean over frames and sensors of the squared vector difference (g²)."""
    return float(np.mean(np.sum((np.asarray(a_g) - np.asarray(b_g)) ** 2, axis=-1)))

