"""Calibration wizard: a pure-logic, step-by-step state machine the console drives through the gateway.

Steps (``STEPS``): ``assign`` sensors to segments -> ``placement`` check (live tilt from gravity) -> ``npose``
static capture (auto-start after every sensor has been still for ``still_required_s``, auto-reject on movement)
-> ``tap`` (sync spike on one sensor, for the IMU-camera lag check; may be skipped) -> ``review`` (quality, per
sensor pass/fail) -> ``done``. Any step can be redone alone (:meth:`CalibrationWizard.redo`): the others' results
are kept and the wizard returns to the first unfinished step afterwards.

Why time comes from the samples, not a wall clock: the same wizard then runs live, on a replayed take, and in
tests, deterministically. Input: :meth:`push` (sensor id, times s, accelerations g, and the orientation
quaternions of a sensor that streams them). Output: :meth:`snapshot`, a JSON-ready dict for the console, and
:meth:`record`, the versioned :class:`CalibrationRecord`.

Orientation sensors (issue 18): a sensor that streamed its orientation (sensor -> its device's own earth frame,
Z up, yaw arbitrary per sensor) throughout the still capture also gets its earth frame's yaw and its strapping,
solved against the segment's nominal sensor orientation in the pose
(`engine.mocap.orientation_calibration.OrientationCalibration.from_still_pose`), so the engine can pose each
segment with its yaw relative to the pelvis. Accelerometer-only sensors are calibrated exactly as before.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from typing import Any

import numpy as np

from engine.mocap import quaternions
from engine.mocap.orientation_calibration import OrientationCalibration
from gateway.calibration.alignment import (
    UP, norm_error_g, rotation_angle_deg, sensor_to_segment_rotation, tilt_deg,
)
from gateway.calibration.buffer import SampleBuffer
from gateway.calibration.pose import POSE_INSTRUCTIONS
from gateway.calibration.record import CalibrationRecord, SensorCalibration
from gateway.calibration.signals import TapEvent, detect_tap, stillness

STEPS = ("assign", "placement", "npose", "tap", "review", "done")
SNAPSHOT_VERSION = 1


@dataclass(frozen=True)
class SegmentSpec:
    """Where a sensor goes: ``nominal_rotation`` (3, 3) sensor -> segment as mounted by the book, and
    ``expected_up`` (3,), world up in segment coordinates in the calibration pose the subject holds. The default
    ``(0, 1, 0)`` means that the segment frame is world-aligned in that pose. That holds in an engine skeleton's
    zero pose, which is a T-pose for CMU; the standard set-up's N-pose uses ``gateway.calibration.pose``.

    ``pose_orientation_wxyz`` (4,): the nominally mounted sensor's orientation (sensor -> world, facing +Z) in that
    pose, what an orientation sensor's reading is solved against; None: orientations are not calibrated."""

    nominal_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    expected_up: np.ndarray = field(default_factory=lambda: UP.copy())
    pose_orientation_wxyz: np.ndarray | None = None


@dataclass(frozen=True)
class WizardConfig:
    """Thresholds (g, s, degrees). ``still_std_g`` gates both std(|a|) and each axis' std."""

    still_required_s: float = 1.0
    capture_s: float = 2.0
    still_std_g: float = 0.02
    placement_max_tilt_deg: float = 35.0
    max_correction_deg: float = 35.0
    norm_tolerance_g: float = 0.05
    tap_threshold_g: float = 1.0
    max_gap_s: float = 0.5
    live_window_s: float = 0.25
    eval_interval_s: float = 0.05


def segment_specs_from_placements(placements: list[Any], pose_rotations: np.ndarray | None = None
                                  ) -> dict[str, SegmentSpec]:
    """Specs from ``engine.mocap.standard_placements(...)`` (name -> nominal rotation). ``expected_up`` is world
    up, i.e. the calibration pose is the skeleton's zero pose (a T-pose for the shipped CMU skeleton), unless
    ``pose_rotations`` (J, 3, 3), the joints' global rotations in the pose the subject really holds (e.g.
    ``gateway.calibration.pose.reference_npose(skeleton)[1]``, what ``CalibrationService.standard`` uses), is
    given: then each segment's up is world up seen in that joint's frame, ``G_j^T (0, 1, 0)``, and its nominal
    sensor's orientation in the pose is ``G_j R``: the same pose for the accelerometer and the orientation, so both
    halves of a record describe one strap."""
    specs = {}
    for p in placements:
        world_from_segment = np.eye(3) if pose_rotations is None else np.asarray(pose_rotations, float)[p.joint]
        rotation = np.asarray(p.rotation, float)
        specs[p.name] = SegmentSpec(rotation, world_from_segment.T @ UP,
                                    quaternions.from_matrix(world_from_segment @ rotation))
    return specs


class CalibrationWizard:
    """See the module docstring. Sensor ids are strings (e.g. ``"station0/3"``).

    ``pose`` names the static pose the segments' ``expected_up`` was computed for (``"npose"`` or ``"tpose"``,
    see gateway.calibration.pose); it is shown in the snapshot with instructions for the subject and named in
    placement refusals. ``None``: the caller's own specs, pose not stated."""

    def __init__(self, segments: dict[str, SegmentSpec], config: WizardConfig = WizardConfig(),
                 pose: str | None = None) -> None:
        if not segments:
            raise ValueError("the wizard needs at least one segment to calibrate")
        if pose is not None and pose not in POSE_INSTRUCTIONS:
            raise ValueError(f"unknown calibration pose {pose!r}; known: {', '.join(POSE_INSTRUCTIONS)}")
        self.segments = dict(segments)
        self.config = config
        self.pose = pose
        self.step = "assign"
        self.assignment: dict[str, str] = {}
        self.results: dict[str, SensorCalibration] = {}
        self.tap: dict[str, Any] | None = None
        self.tap_skipped = False
        self.rejections = 0
        self._buffers: dict[str, SampleBuffer] = {}
        self._raw: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {}
        self._completed: set[str] = set()
        self._messages: list[str] = []
        self._now = -np.inf
        self._phase_start_s = -np.inf
        self._capturing = False
        self._last_eval_s = -np.inf

    # ------------------------------------------------------------------ operator actions
    def assign(self, sensor_id: str, segment: str) -> None:
        """Put ``sensor_id`` on ``segment`` (replacing whatever sensor was there)."""
        if segment not in self.segments:
            raise ValueError(f"unknown segment {segment!r}; known: {sorted(self.segments)}")
        for other, seg in list(self.assignment.items()):
            if seg == segment and other != sensor_id:
                self.unassign(other)
        if self.assignment.get(sensor_id) != segment:
            self._invalidate(sensor_id)
            self._completed.discard("placement")  # a newly placed sensor has not been checked yet
        self.assignment[sensor_id] = segment

    def unassign(self, sensor_id: str) -> None:
        if self.assignment.pop(sensor_id, None) is not None:
            self._invalidate(sensor_id)

    def _invalidate(self, sensor_id: str) -> None:
        """A sensor changed segment: its N-pose result no longer applies, so the N-pose must be redone."""
        if self.results.pop(sensor_id, None) is not None:
            self._completed.discard("npose")
            self._say(f"{sensor_id} re-assigned: the N-pose must be captured again")

    def confirm(self) -> bool:
        """The operator's "Next"/"Accept". Returns False (with a message) when the step cannot be left yet."""
        if self.step == "assign":
            if not self.assignment:
                return self._refuse("assign at least one sensor to a segment")
            return self._leave("assign")
        if self.step == "placement":
            problems = [f"{sid} ({self.assignment[sid]}): {r}" for sid, info in self._placement().items()
                        for r in info["reasons"]]
            if problems:
                return self._refuse("placement check failed: " + "; ".join(problems))
            return self._leave("placement")
        if self.step == "tap":
            self.tap_skipped = True
            self._say("sync tap skipped: the IMU-camera lag check will have no tap event")
            return self._leave("tap")
        if self.step == "review":
            if "npose" not in self._completed:
                return self._refuse("no N-pose captured")
            self.step = "done"
            self._say("calibration accepted")
            return True
        return self._refuse(f"nothing to confirm in step {self.step!r} (it advances by itself)")

    def redo(self, step: str) -> None:
        """Go back to ``step`` and clear only its results."""
        if step not in STEPS[:-2]:
            raise ValueError(f"cannot redo {step!r}; steps that can be redone: {list(STEPS[:-2])}")
        self._completed.discard(step)
        if step == "npose":
            self.results.clear()
            self._raw.pop("npose", None)
        elif step == "tap":
            self.tap, self.tap_skipped = None, False
            self._raw.pop("tap", None)
        self._enter(step)
        self._say(f"redoing step {step!r}")

    # ------------------------------------------------------------------ data in
    def push(self, sensor_id: str, t_s: float | np.ndarray, acc_g: np.ndarray,
             quat_wxyz: np.ndarray | None = None) -> None:
        """Samples of one sensor: times ``t_s`` (s, host clock; scalar or (N,)), ``acc_g`` ((3,) or (N, 3)) and, if
        it streams them, its orientations ``quat_wxyz`` ((4,) or (N, 4), sensor -> device earth; NaN rows: none)."""
        buffer = self._buffers.setdefault(sensor_id, SampleBuffer())
        buffer.extend(t_s, acc_g, quat_wxyz)
        self._now = max(self._now, buffer.last_t_s)
        self._advance()
        # Keep what the current step still needs: the tap search window, the capture window, or a few seconds.
        keep_from = self._now - (self.config.still_required_s + self.config.capture_s + 1.0)
        if self.step == "tap" or (self.step == "npose" and self._capturing):
            keep_from = min(keep_from, self._phase_start_s)
        buffer.drop_before(keep_from)

    # ------------------------------------------------------------------ state machine
    def _advance(self) -> None:
        # Evaluate at most every eval_interval_s of sample time: every sensor's packet triggers a push, and the
        # window statistics of all sensors need not be recomputed that often.
        if self._now - self._last_eval_s < self.config.eval_interval_s:
            return
        self._last_eval_s = self._now
        if self.step == "npose":
            self._advance_npose()
        elif self.step == "tap":
            self._advance_tap()

    def _advance_npose(self) -> None:
        cfg = self.config
        sensors = list(self.assignment)
        if not self._capturing:
            # Each sensor's window ends at its own latest sample: sensors arrive in separate packets, so at any
            # push the others are up to one packet behind.
            last = {s: self._buffers[s].last_t_s if s in self._buffers else -np.inf for s in sensors}
            stats = [self._stillness(s, last[s] - cfg.still_required_s, last[s]) for s in sensors]
            fresh = all(self._now - t <= cfg.max_gap_s for t in last.values())
            if fresh and all(st.span_s >= 0.9 * cfg.still_required_s and st.worst_g <= cfg.still_std_g
                             for st in stats):
                self._capturing = True
                self._phase_start_s = self._now
                self._say(f"everyone still for {cfg.still_required_s:g} s: capturing the N-pose, hold still")
            return
        t0, t1 = self._phase_start_s, self._phase_start_s + cfg.capture_s
        for sid in sensors:
            st = self._stillness(sid, t0, min(self._now, t1))
            if st.span_s >= 0.2 and st.worst_g > cfg.still_std_g:
                return self._reject(f"sensor {sid} ({self.assignment[sid]}) moved: std {st.worst_g:.3f} g > "
                                    f"{cfg.still_std_g:g} g")
            gap = self._now - self._buffers[sid].last_t_s if sid in self._buffers else np.inf
            if gap > cfg.max_gap_s:
                return self._reject(f"sensor {sid} ({self.assignment[sid]}) stopped sending for {gap:.1f} s")
        if all(self._buffers[s].last_t_s >= t1 for s in sensors):
            self._finish_npose(t0, t1)

    def _reject(self, reason: str) -> None:
        self.rejections += 1
        self._capturing = False
        self._say(f"N-pose rejected: {reason}; waiting for stillness again")

    def _finish_npose(self, t0: float, t1: float) -> None:
        cfg = self.config
        self._raw["npose"] = {}
        oriented = 0
        for sid, segment in self.assignment.items():
            t, acc = self._buffers[sid].window(t0, t1)
            quat = self._buffers[sid].quat_window(t0, t1)
            streamed = np.isfinite(quat).all(axis=1)
            self._raw["npose"][sid] = (t.copy(), acc.copy()) + ((quat.copy(),) if streamed.any() else ())
            spec = self.segments[segment]
            mean = acc.mean(axis=0)
            rotation = sensor_to_segment_rotation(mean, spec.nominal_rotation, spec.expected_up)
            correction = rotation_angle_deg(rotation @ spec.nominal_rotation.T)
            err = norm_error_g(mean)
            std = stillness(t, acc).worst_g
            reasons = []
            if correction > cfg.max_correction_deg:
                reasons.append(f"mounted {correction:.0f} deg away from the nominal orientation "
                               f"(limit {cfg.max_correction_deg:g}); check the placement")
            if abs(err) > cfg.norm_tolerance_g:
                reasons.append(f"|a| is {err:+.3f} g off 1 g while still (limit +-{cfg.norm_tolerance_g:g} g): "
                               "accelerometer bias or scale error")
            quality = float(np.clip(min(1 - correction / cfg.max_correction_deg, 1 - abs(err) / cfg.norm_tolerance_g,
                                        1 - std / cfg.still_std_g), 0.0, 1.0))
            self.results[sid] = SensorCalibration(sid, segment, rotation, mean, err, std, correction, quality,
                                                  not reasons, reasons, *self._orientation(quat[streamed], spec),
                                                  quaternions.from_matrix(spec.nominal_rotation.T @ rotation))
            oriented += self.results[sid].orientation_yaw_rad is not None
        self._capturing = False
        self._say("N-pose captured" + (f" (orientation calibrated for {oriented} of {len(self.assignment)} sensors)"
                                       if oriented else ""))
        self._leave("npose")

    @staticmethod
    def _orientation(quat_wxyz: np.ndarray, spec: SegmentSpec) -> tuple[float | None, np.ndarray | None]:
        """(yaw rad, strapping (4,)) of a sensor from its orientations during the capture, or (None, None) when it
        streamed none or its segment's pose orientation is not known."""
        if not len(quat_wxyz) or spec.pose_orientation_wxyz is None:
            return None, None
        solved = OrientationCalibration.from_still_pose(quat_wxyz[:, None], spec.pose_orientation_wxyz[None])
        return float(solved.yaw_rad[0]), solved.mount_wxyz[0]

    def _advance_tap(self) -> None:
        events: list[tuple[TapEvent, str]] = []
        for sid in self.assignment:
            if sid in self._buffers:
                t, acc = self._buffers[sid].window(self._phase_start_s)
                event = detect_tap(t, acc, self.config.tap_threshold_g)
                if event is not None:
                    events.append((event, sid))
        if not events:
            return
        event, sid = min(events, key=lambda e: e[0].t_s)
        self.tap = {"sensor_id": sid, "segment": self.assignment[sid], "t_s": event.t_s, "peak_g": event.peak_g}
        self._raw["tap"] = {s: tuple(a.copy() for a in self._buffers[s].window(self._phase_start_s))
                            for s in self.assignment if s in self._buffers}
        self._say(f"sync tap on {sid} at t = {event.t_s:.3f} s ({event.peak_g:.1f} g)")
        self._leave("tap")

    # ------------------------------------------------------------------ helpers
    def _stillness(self, sensor_id: str, t0: float, t1: float):
        buffer = self._buffers.get(sensor_id)
        if buffer is None:
            return stillness(np.empty(0), np.empty((0, 3)))
        return stillness(*buffer.window(t0, t1))

    def _leave(self, step: str) -> bool:
        self._completed.add(step)
        following = [s for s in ("placement", "npose", "tap") if s not in self._completed]
        self._enter(following[0] if following else "review")
        return True

    def _enter(self, step: str) -> None:
        self.step = step
        self._capturing = False
        self._phase_start_s = self._now
        self._last_eval_s = -np.inf

    def _refuse(self, message: str) -> bool:
        self._say(message)
        return False

    def _say(self, message: str) -> None:
        self._messages = (self._messages + [message])[-20:]

    def _pose_label(self) -> str:
        return {"npose": "N-pose (arms down)", "tpose": "T-pose (arms out)"}[self.pose]

    def _placement(self) -> dict[str, dict[str, Any]]:
        """Live tilt per assigned sensor from its last ``live_window_s`` of samples."""
        out = {}
        for sid, segment in self.assignment.items():
            spec = self.segments[segment]
            buffer = self._buffers.get(sid)
            reasons: list[str] = []
            tilt = None
            if buffer is None or not len(buffer):
                reasons.append("no samples yet")
            else:
                _, acc = buffer.window(buffer.last_t_s - self.config.live_window_s)
                tilt = tilt_deg(acc.mean(axis=0), spec.nominal_rotation, spec.expected_up)
                if tilt > 120:
                    reasons.append(f"tilted {tilt:.0f} deg: upside down?")
                elif tilt > self.config.placement_max_tilt_deg:
                    hint = (f"; check the strap, and that the subject holds the {self._pose_label()}"
                            if self.pose else "")
                    reasons.append(f"tilted {tilt:.0f} deg from the expected mounting "
                                   f"(limit {self.config.placement_max_tilt_deg:g}){hint}")
            out[sid] = {"tilt_deg": tilt, "reasons": reasons}
        return out

    # ------------------------------------------------------------------ outputs
    def quality(self) -> dict[str, Any]:
        """Overall score 0-100 (mean per-sensor quality), grade, pass (all sensors pass and N-pose done)."""
        if not self.results:
            return {"score": 0.0, "grade": "none", "passed": False}
        score = 100.0 * float(np.mean([r.quality for r in self.results.values()]))
        grade = "good" if score >= 70 else "fair" if score >= 40 else "poor"
        return {"score": round(score, 1), "grade": grade, "passed": all(r.passed for r in self.results.values())}

    def snapshot(self) -> dict[str, Any]:
        """JSON-serialisable state for the console (see docs/camera-calibration.md for the fields)."""
        cfg = self.config
        placement = self._placement()
        sensors: dict[str, Any] = {}
        for sid in sorted(set(self._buffers) | set(self.assignment)):
            buffer = self._buffers.get(sid)
            live_t0 = (buffer.last_t_s if buffer is not None else 0.0) - cfg.still_required_s
            st = self._stillness(sid, live_t0, np.inf)
            result = self.results.get(sid)
            sensors[sid] = {
                "segment": self.assignment.get(sid),
                "stillness": st.meter(cfg.still_std_g) if st.span_s > 0 else 0.0,
                "std_g": None if not np.isfinite(st.worst_g) else st.worst_g,
                "tilt_deg": placement.get(sid, {}).get("tilt_deg"),
                "placement_ok": None if sid not in placement else not placement[sid]["reasons"],
                "placement_reasons": placement.get(sid, {}).get("reasons", []),
                "passed": None if result is None else result.passed,
                "reasons": [] if result is None else list(result.reasons),
                "correction_deg": None if result is None else result.correction_deg,
                "norm_error_g": None if result is None else result.norm_error_g,
                "rotation_wxyz": None if result is None else result.to_dict()["rotation_wxyz"],
                "orientation_yaw_deg": None if result is None or result.orientation_yaw_rad is None
                else float(np.degrees(result.orientation_yaw_rad)),
            }
        countdown = None
        if self.step == "npose" and self._capturing:
            countdown = max(0.0, self._phase_start_s + cfg.capture_s - self._now)
        phase = {"npose": "capturing" if self._capturing else "waiting_for_stillness",
                 "tap": "waiting_for_tap"}.get(self.step, "waiting_for_operator" if self.step != "done" else "done")
        return {
            "snapshot_version": SNAPSHOT_VERSION,
            "step": self.step,
            "steps": list(STEPS),
            "pose": self.pose,
            "pose_instructions": POSE_INSTRUCTIONS.get(self.pose or ""),
            "completed": [s for s in STEPS if s in self._completed],
            "phase": phase,
            "countdown_s": countdown,
            "time_s": None if not np.isfinite(self._now) else self._now,
            "sensors": sensors,
            "unassigned_segments": sorted(set(self.segments) - set(self.assignment.values())),
            "tap": self.tap,
            "tap_skipped": self.tap_skipped,
            "rejections": self.rejections,
            "quality": self.quality(),
            "messages": list(self._messages),
        }

    def record(self, subject: str = "", take: str = "") -> CalibrationRecord:
        """The versioned record (results + raw samples of each captured step); needs a captured N-pose."""
        if "npose" not in self._completed:
            raise RuntimeError("no N-pose captured yet: nothing to record")
        q = self.quality()
        return CalibrationRecord(
            sensors=dict(self.results), quality_score=q["score"], grade=q["grade"], passed=q["passed"],
            tap=self.tap, subject=subject, take=take, created_utc=datetime.now(timezone.utc).isoformat(),
            config=asdict(self.config), raw={step: dict(per) for step, per in self._raw.items()},
        )
