"""What the worn sensors and the overhead camera would report on a take, simulated from its truth.

Accelerometers: engine.mocap virtual sensors computed clip by clip (a seam between two clips is a pose jump
that no body makes, so it must not become a finite-difference spike), concatenated, then perturbed ONCE by a
`SensorErrorModel` so bias, gain and mounting errors stay constant over the take, as one set of hardware
would. Camera: root ground position and hips heading with Gaussian noise, one fix every 1/rate_hz seconds;
samples between fixes are NaN (the motion graph skips the term; `filled_camera` holds the last fix for the
baselines that need a value every frame).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from engine.errors import CourtsideError
from engine.mocap import (Motion, SensorErrorModel, Skeleton, resample, standard_placements, virtual_accelerometers,
                          virtual_gyroscopes)
from engine.mocap import quaternions as quat
from engine.mocap.orientation import OrientationErrorModel, random_rotations, virtual_orientations
from engine.mocap.orientation_calibration import OrientationCalibration, pose_sensor_orientations
from engine.mocap.take_calibration import MotionPrior, PoseSpec, calibrate_take

from .takes import Take


@dataclass(frozen=True)
class CameraModel:
    """The overhead camera as the evaluation simulates it (issue 11: 5 cm / 10° noise)."""

    position_noise_m: float = 0.05
    heading_noise_rad: float = float(np.radians(10.0))
    rate_hz: float = 30.0


@dataclass
class SimulatedCameraTrack:
    """Camera fixes on the take's frame grid; NaN where the camera gave no fix."""

    position_m: np.ndarray  # (T, 2)
    heading_rad: np.ndarray  # (T,)

    def filled(self) -> tuple[np.ndarray, np.ndarray]:
        """Every frame holds the latest fix (frames before the first fix take the first)."""
        ok = np.isfinite(self.heading_rad) & np.all(np.isfinite(self.position_m), axis=1)
        if not ok.any():
            raise CourtsideError("the camera track has no fix")
        idx = np.maximum.accumulate(np.where(ok, np.arange(len(ok)), -1))
        idx = np.where(idx < 0, np.flatnonzero(ok)[0], idx)
        return self.position_m[idx], self.heading_rad[idx]


def camera_track(take: Take, model: CameraModel, rng: np.random.Generator) -> SimulatedCameraTrack:
    """Noisy fixes at `model.rate_hz` (at most the take rate), the first at t = 0."""
    if not 0 < model.rate_hz <= take.fps + 1e-9:
        raise CourtsideError(f"camera rate {model.rate_hz:g} Hz must be in (0, {take.fps:g}] (the take rate)")
    n = take.n_frames
    fix = np.unique(np.round(np.arange(0.0, n / take.fps, 1.0 / model.rate_hz) * take.fps).astype(int))
    fix = fix[fix < n]
    pos = np.full((n, 2), np.nan)
    head = np.full(n, np.nan)
    pos[fix] = take.ground_m[fix] + rng.normal(0.0, model.position_noise_m, (len(fix), 2))
    head[fix] = take.heading_rad[fix] + rng.normal(0.0, model.heading_noise_rad, len(fix))
    return SimulatedCameraTrack(pos, head)


def per_segment(take: Take, fps: float, reading: Callable[[Motion], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """`reading` of each segment resampled to `fps`, concatenated, with each output frame's take time (s)."""
    out, times = [], []
    for seg in take.segments:
        m = resample(seg.motion, fps)
        out.append(reading(m))
        times.append(seg.start / take.fps + np.arange(m.n_frames) / fps)
    return np.concatenate(out), np.concatenate(times)


def accelerometers(take: Take, sensor_names: tuple[str, ...] | list[str], error_model: SensorErrorModel | None,
                   rng: np.random.Generator, fps: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(acc (T', S, 3) g, times (T',) s) of the named standard sensors at `fps` (default: the take rate), each
    segment's sensors placed on its own skeleton (performers differ in size)."""
    fps = take.fps if fps is None else fps
    acc, times = per_segment(take, fps, lambda m: virtual_accelerometers(m, standard_placements(m.skeleton, sensor_names)))
    return (error_model.apply(acc, fps, rng) if error_model is not None else acc), times


def gyroscopes(take: Take, sensor_names: tuple[str, ...] | list[str], fps: float | None = None) -> np.ndarray:
    """(T', S, 3) rad/s, clean (the HMM's IMU feature; no gyro error model exists in engine.mocap yet)."""
    return per_segment(take, take.fps if fps is None else fps,
                       lambda m: virtual_gyroscopes(m, standard_placements(m.skeleton, sensor_names)))[0]


STRAPPINGS = ("nominal", "random")
CALIBRATION_SOURCES = ("pose", "motion")


@dataclass(frozen=True)
class CalibrationCapture:
    """The still N-pose the athlete holds before the take (what the wizard asks for): `seconds` of it, held with
    `posing_error_deg` (sd) of each segment's orientation off the reference pose -- people do not hold a template
    exactly -- and solved against the reference pose on the database's skeleton.

    Issue 29's real-recording conditions: `strapping` "random" straps every sensor by a rotation drawn uniformly
    over all rotations (its accelerometer too); `start_pose` (npose, tpose, or apose:DEG, the arms DEG out from
    hanging) is the pose held instead of the N-pose, and the calibration is then solved FROM THE TAKE by what
    `courtside calibrate` runs (engine.mocap.take_calibration: the still stretch found, an A-pose's arm angle
    fitted, each strap's twist from the motion against the database); `source` "motion" holds no pose at all and
    calibrates from the motion alone; `north` is what that solve is told of the sensors' earth frames, as
    `courtside calibrate --north` (auto: found; shared: a magnetometer's one north; own: 6-axis, one each).
    Defaults: the wizard's N-pose with today's straps and solve."""

    seconds: float = 2.0
    posing_error_deg: float = 8.0
    strapping: str = "nominal"
    start_pose: str | None = None
    source: str = "pose"
    north: str = "auto"

    @property
    def from_take(self) -> bool:
        """Is the calibration solved from the take (`calibrate_take`) rather than the wizard's N-pose solve?"""
        return (self.strapping != "nominal" or self.start_pose is not None or self.source != "pose"
                or self.north != "auto")


def _true_orientations(take: Take, sensor_names: tuple[str, ...] | list[str], fps: float) -> np.ndarray:
    return per_segment(take, fps,
                       lambda m: virtual_orientations(m, standard_placements(m.skeleton, sensor_names)))[0]


def orientations(take: Take, sensor_names: tuple[str, ...] | list[str], error_model: OrientationErrorModel,
                 rng: np.random.Generator, fps: float | None = None) -> np.ndarray:
    """(T', S, 4) device-earth quaternions (Z up, yaw per sensor) of the named standard sensors at `fps` (default:
    the take rate): the true orientations segment by segment, then ONE draw of `error_model` over the take (the
    per-sensor yaw offsets and drifts of one set of hardware)."""
    fps = take.fps if fps is None else fps
    return error_model.apply(_true_orientations(take, sensor_names, fps), fps, rng)


def calibrated_orientations(take: Take, sensor_names: tuple[str, ...] | list[str], error_model: OrientationErrorModel,
                            rng: np.random.Generator, capture: CalibrationCapture, reference_skeleton: Skeleton,
                            fps: float | None = None) -> tuple[np.ndarray, OrientationCalibration]:
    """`orientations`, but the readings start with the athlete holding the N-pose for `capture.seconds` (facing
    the take's first heading, on the take's first skeleton, each segment off the template by the posing error):
    returns the take's readings and the calibration solved from the capture against the reference pose on
    `reference_skeleton` (the database's), as the wizard would."""
    fps = take.fps if fps is None else fps
    n_capture = max(1, int(round(capture.seconds * fps)))
    held = _held_pose(take, sensor_names, capture, rng)
    q = np.concatenate([np.repeat(held[None], n_capture, axis=0), _true_orientations(take, sensor_names, fps)])
    readings = error_model.apply(q, fps, rng)
    template = pose_sensor_orientations(reference_skeleton, sensor_names)
    return readings[n_capture:], OrientationCalibration.from_still_pose(readings[:n_capture], template)


def _held_pose(take: Take, sensor_names: tuple[str, ...] | list[str], capture: CalibrationCapture,
               rng: np.random.Generator) -> np.ndarray:
    """(S, 4) true sensor orientations of the start pose held (facing the take's first heading, on its first
    skeleton, each segment off the template by the posing error)."""
    spec = PoseSpec.parse(capture.start_pose or "npose")
    held = pose_sensor_orientations(take.segments[0].motion.skeleton, sensor_names, spec.name,
                                    heading_rad=float(take.heading_rad[0]),
                                    arm_deg=(70.0 if spec.arm_deg is None else spec.arm_deg)
                                    if spec.name == "apose" else None)
    return quat.multiply(random_rotations(rng, len(held), np.radians(capture.posing_error_deg)), held)


def take_calibrated_sensors(take: Take, sensor_names: tuple[str, ...] | list[str], acc_g: np.ndarray,
                            error_model: OrientationErrorModel, rng: np.random.Generator, capture: CalibrationCapture,
                            graph) -> tuple[np.ndarray, np.ndarray, OrientationCalibration]:
    """Issue 29's capture (`CalibrationCapture.from_take`): the sensors strapped as `capture.strapping` says,
    the start pose (or none) before the take, and the calibration solved from those readings by
    `calibrate_take` against `graph` (its skeleton's poses, its nodes as the database; the pose family is not
    told: an A-pose of unknown arm angle, 0 = N-pose, 90 = T-pose arms, found from the tilts and the motion).
    Returns (the take's accelerations `acc_g` (T, S, 3) as the strapped sensors read them, turned back by the
    solved strapping -- what `synthesize --calibration` does to a take --, the take's orientation readings,
    the calibration)."""
    fps = take.fps
    n = len(sensor_names)
    strap = quat.normalize(rng.normal(size=(n, 4))) if capture.strapping == "random" else quat.identity((n,))
    truth = _true_orientations(take, sensor_names, fps)
    held_n = 0 if capture.source == "motion" else max(1, int(round(capture.seconds * fps)))
    if held_n:
        truth = np.concatenate([np.repeat(_held_pose(take, sensor_names, capture, rng)[None], held_n, 0), truth])
    readings = error_model.apply(quat.multiply(truth, strap[None]), fps, rng)
    pose = PoseSpec("none") if capture.source == "motion" else PoseSpec("apose")
    try:
        solved = calibrate_take(readings, fps, list(sensor_names), graph.skeleton, pose, MotionPrior.from_graph(graph),
                                north=capture.north)
    except ValueError as exc:
        raise CourtsideError(f"simulated calibration: {exc}") from None
    cal = solved.orientation
    strapped = quat.rotate(quat.conjugate(strap)[None], acc_g)  # a_sensor = M⁻¹ a_nominal
    corrected = quat.rotate(cal.mount_wxyz[None], strapped)
    return corrected, readings[held_n:], cal
