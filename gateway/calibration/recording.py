"""Sensor-to-segment calibration from an ordinary recording (no perfect N-pose needed).

The live wizard waits for a still N-pose (std <= 0.02 g). Real takes rarely have one: in a 50 s acting take the
stillest moment had a forearm std of ~0.12 g. This calibrates from what a take does have:

1. **Gravity from quasi-static windows, weighted by stillness.** The take is cut into ``window_s`` windows; a
   window counts when every sensor's std (of |a| and of each axis) is below ``max_std_g`` and its mean norm is
   within ``norm_band_g`` of 1 g; its weight is ``1 / (std² + floor²)`` with std the worst sensor's, so a
   stiller window counts more but many slightly moving ones still add up (their linear accelerations average
   out). Per sensor, only the dominant cluster of window gravity directions is kept (within
   ``cluster_deg`` of the weighted mean, iterated), so a stretch sitting or leaning does not pull the estimate.
   These windows are taken to be the subject standing relaxed, i.e. the reference N-pose of
   ``gateway.calibration.pose`` (arms hanging, legs straight): that gives each segment's expected up.
2. **Heading about gravity.** One gravity direction leaves the rotation about it free (the wizard resolves it by
   assuming the nominal mounting). For the pelvis and the shanks it comes from *walking*: over the moving
   windows, the acceleration perpendicular to the sensor's gravity direction, filtered around the cadence, has a
   principal axis along the segment's forward axis in the N-pose (``G_jᵀ ẑ``). The axis has no sign; the sign
   nearer the nominal mounting is taken; an ambiguous axis (share below ``min_heading_share``) is not used. Not
   for forearms (they twist with the arm swing) nor the chest (it counter-rotates): their walking axes were
   14-47° and up to 41° off forward, often with a clear share, so they keep the nominal heading (and say so)
   unless a **second still pose** inclines the segment (>= ``second_pose_min_deg``; ``SECOND_POSES``: a T-pose
   for the arms, a forward bow for pelvis and chest, a long sit for the shanks, whose walking swing plane follows
   the actor's toe-out) and fixes all three angles with sign: all gravity directions go into one Wahba/Kabsch
   fit.
3. **Per-sensor quality** ``min(stillness, consistency, heading)`` in 0..1: stillness ``1 - std/max_std_g`` of the
   windows used, consistency = weight fraction inside the dominant cluster, heading = the walking axis' share
   of horizontal variance (``(λ1 - λ2)/(λ1 + λ2)``, 1 with a second pose). An accelerometer-only sensor whose
   measured up is more than 90° from where its placement puts it is flagged as **flipped** (strapped upside down,
   or the Bandai-style 180° roll), and fails.

4. **Orientation sensors** (a take with ``quat_wxyz``, issues 18 and 29): each sensor's earth-frame yaw and
   strapping from `engine.mocap.take_calibration.calibrate_take` (the pose the take starts with, found or
   declared: N-pose, T-pose, an A-pose of any arm angle, or none; against the database of a graph when one is
   given). Any strapping is solved (upside down, rolled, far off nominal): such a sensor is never failed for its
   mounting, and its ``rotation`` is its placement's nominal rotation times that strapping (``R = N M``), so the
   accelerometer and the orientation halves of the record describe one strap.

The result is the wizard's :class:`CalibrationRecord` (same schema, same rotations convention), so
``courtside build-graph --calibration`` / ``courtside synthesize --calibration`` use it unchanged.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from typing import Any

import numpy as np

from engine.mocap import quaternions
from engine.mocap.take_calibration import MotionPrior, PoseSpec, TakeCalibration, calibrate_take
from gateway.calibration.alignment import (UP, norm_error_g, rotation_angle_deg, rotation_from_directions,
                                           sensor_to_segment_rotation, tilt_deg)
from gateway.calibration.record import CalibrationRecord, SensorCalibration

FORWARD = np.array([0.0, 0.0, 1.0])
# segments whose principal walking axis is their forward axis, as measured (bench/bench_calibrate.py): the
# pelvis and the shank (shin and ankle sensors ride it). Forearms twist with the arm swing and the chest
# counter-rotates: their axes were 14-47° (forearms) and up to 41° (chest) off, often with a clear share.
WALKING_HEADING_SEGMENTS = ("lower_back", "left_shin", "right_shin", "left_ankle", "right_ankle")


@dataclass(frozen=True)
class RecordingCalibrationConfig:
    """Thresholds (s, g, degrees) of the recording calibration (module docstring)."""

    window_s: float = 0.5
    max_std_g: float = 0.15
    std_floor_g: float = 0.01
    norm_band_g: float = 0.15
    cluster_deg: float = 20.0
    moving_std_g: float = 0.15
    cadence_band_hz: tuple[float, float] = (1.2, 3.5)  # steps/s of walking (1.6-2.2) and running (2.5-3.3)
    # pass bands of the walking-axis PCA, in multiples of the step frequency (measured: bench/bench_calibrate.py)
    pelvis_band: tuple[float | None, float] = (0.75, 1.5)  # fore-aft pelvis acceleration repeats every step
    segment_band: tuple[float | None, float] = (None, 1.5)  # shins/chest: the swing, without impacts
    min_heading_share: float = 0.4  # chest on CMU 16_32 + 16_11: share 0.26, axis 40° off
    flipped_deg: float = 90.0
    max_correction_deg: float = 60.0
    min_still_windows: int = 2
    pose_margin_s: float = 1.5  # moving windows this close to a held second pose are not walking
    second_pose_min_deg: float = 45.0  # a smaller inclination change fixes the heading worse than walking


# second still poses `courtside calibrate` knows, and the segments each one is meant to incline
SECOND_POSES = {"tpose": ("left_forearm", "right_forearm", "left_wrist", "right_wrist"),
                "bow": ("lower_back", "chest"),
                "sit": ("left_shin", "right_shin", "left_ankle", "right_ankle")}


@dataclass(frozen=True)
class SegmentPose:
    """Where a sensor goes and what its segment does in the poses: nominal rotation (sensor -> segment), up and
    forward (segment frame) in the reference standing pose, up in each second pose it takes part in, and the
    nominally mounted sensor's orientation (sensor -> world, quaternion) in the standing pose (None: orientations
    not calibrated)."""

    nominal_rotation: np.ndarray
    up: np.ndarray
    forward: np.ndarray
    up_in: dict[str, np.ndarray] = field(default_factory=dict)
    orientation_wxyz: np.ndarray | None = None


@dataclass(frozen=True)
class TakeStart:
    """How the orientation sensors of a take are calibrated (`engine.mocap.take_calibration`): the ``pose`` the
    take starts with (default: found, an A-pose of any arm angle from 0 = N-pose to 90 = T-pose arms, in the first
    still stretch), the ``skeleton`` the poses are built on (None: the shipped CMU skeleton; the same one
    `standard_segment_poses` was given), its identity for the record (``skeleton_id``,
    `engine.mocap.calibrated.skeleton_identity`) and the database ``prior`` (a graph's; None: each strap's twist
    about the pose's vertical is not observed and the smallest strap is taken, and ``pose none`` is refused) and
    whether the sensors share one earth frame (``north``: auto, shared -- 9-axis filters --, own -- 6-axis)."""

    pose: PoseSpec = PoseSpec("apose")
    skeleton: Any = None
    skeleton_id: dict | None = None
    prior: MotionPrior | None = None
    north: str = "auto"

    def solve(self, quat_wxyz: np.ndarray, fps: float, segments: list[str]) -> TakeCalibration:
        """The take's orientation calibration; ValueError with the reason when it has none to give."""
        from engine.mocap import load_clip, sample_clips

        skeleton = self.skeleton if self.skeleton is not None else load_clip(sample_clips()["16_01"]).skeleton
        return calibrate_take(quat_wxyz, fps, segments, skeleton, self.pose, self.prior, north=self.north)


def standard_segment_poses(names: list[str], second_poses: tuple[str, ...] = (), skeleton: Any = None
                           ) -> dict[str, SegmentPose]:
    """Segment poses of the engine's standard placements, reference pose = N-pose, on ``skeleton`` (an upright
    T-pose zero pose, e.g. after ``engine.mocap.rebase_to_tpose``); default: the shipped CMU skeleton (the
    set-up of ``CalibrationService.standard`` and of ``courtside build-graph --sample``)."""
    from engine.mocap import load_clip, sample_clips, standard_placements
    from gateway.calibration.pose import pose_rotations, reference_bow, reference_long_sit

    unknown = [p for p in second_poses if p not in SECOND_POSES]
    if unknown:
        raise ValueError(f"unknown second pose(s) {unknown}; known: {', '.join(SECOND_POSES)}")
    skeleton = skeleton if skeleton is not None else load_clip(sample_clips()["16_01"]).skeleton
    placements = standard_placements(skeleton, names)
    npose = pose_rotations(skeleton, "npose")
    builders = {"bow": reference_bow, "sit": reference_long_sit}
    others = {p: builders[p](skeleton) if p in builders else pose_rotations(skeleton, p) for p in second_poses}
    return {p.name: SegmentPose(p.rotation, npose[p.joint].T @ UP, npose[p.joint].T @ FORWARD,
                                {pose: rots[p.joint].T @ UP for pose, rots in others.items()
                                 if p.name in SECOND_POSES[pose]},
                                quaternions.from_matrix(npose[p.joint] @ p.rotation))
            for p in placements}


def _windows(acc: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per window of n samples: mean (W, S, 3) and worst std (W, S) of |a| and of each axis."""
    w = acc.shape[0] // n
    blocks = acc[: w * n].reshape(w, n, acc.shape[1], 3)
    norm_std = np.linalg.norm(blocks, axis=-1).std(axis=1)
    return blocks.mean(axis=1), np.maximum(norm_std, blocks.std(axis=1).max(axis=-1))


def _dominant(dirs: np.ndarray, weights: np.ndarray, cluster_deg: float) -> tuple[np.ndarray, float]:
    """Mask of the dominant direction cluster (iterated weighted mean) and its share of the weight."""
    keep = np.ones(len(dirs), bool)
    cos = np.cos(np.radians(cluster_deg))
    for _ in range(10):
        mean = (weights[keep, None] * dirs[keep]).sum(axis=0)
        mean /= np.linalg.norm(mean)
        new = dirs @ mean >= cos
        if not new.any() or np.array_equal(new, keep):
            break
        keep = new
    return keep, float(weights[keep].sum() / weights.sum())


def step_frequency_hz(acc: np.ndarray, moving: np.ndarray, ups: np.ndarray, fps: float,
                      band_hz: tuple[float, float]) -> float | None:
    """Cadence (steps/s) of the moving samples: the peak in ``band_hz`` of the summed, normalised spectra of every
    sensor's acceleration along its gravity direction (the trunk bounces once per step; a shin's impacts repeat
    once per stride and add their second harmonic). None when there is too little movement for a spectrum."""
    from scipy.signal import welch

    if moving.sum() < 4 * fps:
        return None
    total = 0.0
    for k in range(acc.shape[1]):
        vertical = acc[moving, k] @ ups[k]
        f, pxx = welch(vertical - vertical.mean(), fs=fps, nperseg=min(int(4 * fps), int(moving.sum())))
        total = total + pxx / max(pxx.sum(), 1e-12)
    sel = (f >= band_hz[0]) & (f <= band_hz[1])
    return float(f[sel][np.argmax(total[sel])]) if sel.any() else None


def _walking_axis(acc: np.ndarray, moving: np.ndarray, up_s: np.ndarray, band: tuple[float | None, float],
                  fps: float) -> tuple[np.ndarray | None, float]:
    """Principal axis (sensor frame, unit, no sign) of the acceleration perpendicular to ``up_s`` over the
    moving samples, after filtering to ``band`` (Hz; low edge None = low-pass), and its share
    ``(λ1 - λ2) / (λ1 + λ2)``."""
    from scipy.signal import butter, sosfiltfilt

    lo, hi = band
    sos = butter(2, hi, "lowpass", fs=fps, output="sos") if lo is None else \
        butter(2, [lo, hi], "bandpass", fs=fps, output="sos")
    a = sosfiltfilt(sos, acc, axis=0)[moving]
    h = a - np.outer(a @ up_s, up_s)
    h = h - h.mean(axis=0)
    vals, vecs = np.linalg.eigh(h.T @ h)  # ascending; the smallest is ~along up_s
    l1, l2 = vals[2], vals[1]
    return vecs[:, 2], float((l1 - l2) / max(l1 + l2, 1e-12))


def calibrate_recording(acc_g: np.ndarray, fps: float, sensor_ids: list[str], segments: list[str],
                        poses: dict[str, SegmentPose], config: RecordingCalibrationConfig = RecordingCalibrationConfig(),
                        second_windows: dict[str, tuple[float, float]] | None = None, subject: str = "",
                        take: str = "", quat_wxyz: np.ndarray | None = None,
                        take_start: TakeStart = TakeStart()) -> CalibrationRecord:
    """Calibrate every sensor of a take ``acc_g`` (T, S, 3) g at ``fps``; ``segments[k]`` is sensor k's standard
    placement name, ``poses`` its :class:`SegmentPose`. ``second_windows``: second pose name -> (start, end) s
    where the subject holds it (see ``SECOND_POSES``). ``quat_wxyz`` (T, S, 4): the sensors' orientations
    (sensor -> device earth; NaN where a sensor has none), whose yaw and strapping are then calibrated too, with
    the pose, skeleton and database of ``take_start`` (`TakeStart`)."""
    acc = np.asarray(acc_g, float)
    n = max(2, int(round(config.window_s * fps)))
    t = np.arange(len(acc)) / fps
    second_windows = dict(second_windows or {})
    masks = {}
    for pose_name_2, (start, end) in second_windows.items():
        masks[pose_name_2] = (t >= start) & (t <= end)
        if masks[pose_name_2].sum() < 2:
            raise ValueError(f"{pose_name_2} window {start:g}-{end:g} s holds no samples of the take "
                             f"(0-{t[-1]:.1f} s)")
    second_mask = np.any(list(masks.values()), axis=0) if masks else np.zeros(len(acc), bool)
    # getting into and out of a held pose is movement but not walking: keep it out of the walking axis
    near_second = np.zeros(len(acc), bool)
    for start, end in second_windows.values():
        near_second |= (t >= start - config.pose_margin_s) & (t <= end + config.pose_margin_s)
    means, stds = _windows(acc, n)
    worst = stds.max(axis=1)
    in_second = second_mask[: len(worst) * n].reshape(len(worst), n).any(axis=1)
    norms = np.linalg.norm(means, axis=-1)
    ok = ~in_second & (worst <= config.max_std_g) & np.all(np.abs(norms - 1.0) <= config.norm_band_g, axis=1)
    if ok.sum() < config.min_still_windows:
        raise ValueError(f"no quasi-static stretch: {int(ok.sum())} of {len(worst)} windows of {config.window_s:g} s "
                         f"have every sensor's std <= {config.max_std_g:g} g and |a| within "
                         f"{config.norm_band_g:g} g of 1 g")
    weights = 1.0 / (worst[ok] ** 2 + config.std_floor_g**2)
    moving = np.zeros(len(acc), bool)
    moving[: len(worst) * n] = np.repeat(~in_second & (worst > config.moving_std_g), n)
    moving &= ~near_second
    results: dict[str, SensorCalibration] = {}
    raw: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    still = []
    for k in range(len(sensor_ids)):
        dirs = means[ok, k] / norms[ok, k, None]
        keep, consistency = _dominant(dirs, weights, config.cluster_deg)
        w = weights[keep]
        gravity = (w[:, None] * means[ok, k][keep]).sum(axis=0) / w.sum()
        still.append((keep, consistency, gravity, float((w * stds[ok, k][keep]).sum() / w.sum())))
    ups = np.array([g / np.linalg.norm(g) for _, _, g, _ in still])
    step_hz = step_frequency_hz(acc, moving, ups, fps, config.cadence_band_hz)
    solved = None if quat_wxyz is None else take_start.solve(quat_wxyz, fps, segments)
    oriented = [] if solved is None else list(solved.sensors)
    for k, (sid, seg) in enumerate(zip(sensor_ids, segments)):
        pose = poses[seg]
        keep, consistency, gravity, std = still[k]
        up_s = ups[k]
        tilt_only = sensor_to_segment_rotation(gravity, pose.nominal_rotation, pose.up)
        sensor_dirs, segment_dirs, reasons = [up_s], [pose.up], []
        heading_term = 0.0
        for other, up_other in pose.up_in.items():
            if other in masks and np.degrees(np.arccos(np.clip(pose.up @ up_other, -1, 1))) >= \
                    config.second_pose_min_deg:
                g2 = acc[masks[other], k].mean(axis=0)
                sensor_dirs.append(g2 / np.linalg.norm(g2))
                segment_dirs.append(up_other)
                heading_term = 1.0
        j = oriented.index(k) if k in oriented else None  # the sensor's column in the orientation solve
        # the strap solved from the orientations, as an accelerometer mounting (R = N M)
        strap = None if j is None else pose.nominal_rotation @ quaternions.to_matrix(solved.orientation.mount_wxyz[j])
        # a walking axis says the heading only where the orientations could not (their twist a guess, no database)
        walks = seg in WALKING_HEADING_SEGMENTS and (strap is None or not solved.twist_observed)
        axis, share = None, 0.0
        if not (heading_term or not walks or step_hz is None):
            band = config.pelvis_band if seg == "lower_back" else config.segment_band
            axis, share = _walking_axis(acc[:, k], moving, up_s, tuple(None if b is None else b * step_hz
                                                                       for b in band), fps)
        if heading_term:  # the second pose fixes the heading with sign (more exactly than walking)
            rotation = rotation_from_directions(np.array(sensor_dirs), np.array(segment_dirs))
        elif axis is not None and share >= config.min_heading_share:
            # the walking axis has no sign: take the one nearer the solved strap, else the nominal mounting
            candidates = [rotation_from_directions(np.array([up_s, sign * axis]), np.array([pose.up, pose.forward]))
                          for sign in (1.0, -1.0)]
            nearer = tilt_only if strap is None else strap
            rotation = min(candidates, key=lambda r: rotation_angle_deg(r @ nearer.T))
            heading_term = share
        else:
            rotation = tilt_only
            why = (f"the walking axis is ambiguous, share {share:.2f} < {config.min_heading_share:g}"
                   if axis is not None else "no walking, no second pose" if walks else
                   "an arm needs a second pose, e.g. --second-pose tpose@START:END" if seg.endswith(("forearm", "wrist"))
                   else "the trunk needs a second pose, e.g. --second-pose bow@START:END")
            reasons.append(f"heading about gravity not observed ({why}): nominal mounting assumed for it")
        yaw = mount = None
        if j is not None:  # any strapping: solved from the orientations, never failed for being far from nominal
            yaw, mount = float(solved.orientation.yaw_rad[j]), solved.orientation.mount_wxyz[j]
            if not heading_term:  # a declared second pose (two gravity directions) observes the accelerometer's
                # heading about gravity, and so does a clear walking axis where the orientations leave the twist a
                # guess; else the strap solved from the orientations is the mounting (with a database, a gesture
                # take's "walking axis" put the shins and pelvis up to 180 deg off: its sign came from the nominal
                # mounting, which says nothing of a random strap)
                rotation = strap
            reasons = [r for r in reasons if not r.startswith("heading about gravity")] + \
                [n for n in solved.notes[j:j + 1] if n]
        correction = rotation_angle_deg(rotation @ pose.nominal_rotation.T)
        flipped = tilt_deg(gravity, pose.nominal_rotation, pose.up)
        measured_only = j is None  # the mounting checks are for accelerometer-only sensors
        if measured_only and flipped > config.flipped_deg:
            reasons.append(f"axes look flipped against the placement: the sensor's up is {flipped:.0f} deg from "
                           "where the placement table puts it (strapped upside down or rolled 180 deg?)")
        elif measured_only and correction > config.max_correction_deg:
            reasons.append(f"mounted {correction:.0f} deg away from the nominal orientation "
                           f"(limit {config.max_correction_deg:g}); check the placement")
        err = norm_error_g(gravity)
        still_term = 1.0 - std / config.max_std_g
        quality = float(np.clip(min(still_term, consistency, heading_term if heading_term else 0.5), 0.0, 1.0))
        passed = not any("flipped" in r or "mounted" in r for r in reasons)
        results[sid] = SensorCalibration(sid, seg, rotation, gravity, err, std, correction, quality, passed, reasons,
                                         yaw, mount, quaternions.from_matrix(pose.nominal_rotation.T @ rotation))
        idx = (np.flatnonzero(ok)[keep][:, None] * n + np.arange(n)).ravel()
        raw[sid] = (t[idx], acc[idx, k]) + ((quat_wxyz[idx, k],) if k in oriented else ())
    score = 100.0 * float(np.mean([r.quality for r in results.values()]))
    grade = "good" if score >= 70 else "fair" if score >= 40 else "poor"
    cfg = {"method": "recording", "pose": "npose" if solved is None else solved.pose.text(),
           **({} if solved is None else {"north": solved.north}),
           **({"north_basis": solved.north_basis} if solved is not None and solved.north_basis else {}),
           "second_windows_s": {k: list(v) for k, v in second_windows.items()}, "fps": fps, **asdict(config)}
    return CalibrationRecord(results, round(score, 1), grade, all(r.passed for r in results.values()), None, subject,
                             take, datetime.now(timezone.utc).isoformat(), cfg, {"still": raw}, take_start.skeleton_id)

