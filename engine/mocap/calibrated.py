"""Calibrated sensor placements: the standard placements with each worn sensor's *measured* mounting.

The gateway's calibration wizard (gateway/calibration, docs/camera-calibration.md) measures, per worn sensor,
the rotation from sensor axes to the segment's joint frame by gravity alignment in a still pose. That is exactly
``SensorPlacement.rotation``; this module swaps it in, so the virtual sensors (and a motion graph built from
them) read what the real, imperfectly strapped sensors read.

The engine must not depend on the gateway, so the record is read here from its JSON (``schema:
courtside.sensor_calibration``, ``schema_version: 1``, written by ``gateway.calibration.CalibrationRecord.save``):
only the per-sensor ``segment`` (= standard placement name), ``rotation`` (3x3), ``gravity_sensor_g``,
``norm_error_g``, ``correction_deg`` and ``passed`` are used, and, for a sensor that streamed its orientation
during the still capture (issue 18), the optional pair ``orientation_yaw_rad`` (its earth frame's yaw about the
world vertical) and ``orientation_mount_wxyz`` (its strapping): `engine.mocap.orientation_calibration`'s
`OrientationCalibration` of that sensor. The pair is optional within ``schema_version: 1`` (older readers ignore
it, records without it read as before), and `orientation_fields` / `read_orientation_fields` are its one
definition, which the gateway's writer and reader use too.

Frames of the orientation pair: the yaw is about the engine world's up, relative to wherever the athlete faced
during the capture (only yaws relative to the pelvis sensor are used), and the strapping maps the sensor's axes
onto the *nominal* sensor frame of its standard placement, which is the same in every skeleton's joint frames (a
placement is defined on the T-pose); so unlike ``rotation`` the pair is not tied to the wizard's skeleton.

Frames: the record's rotations are in the joint frames of the skeleton whose standard placements gave the
calibration its nominal mountings (the shipped CMU skeleton for the live wizard by default; the graph's own
skeleton for `courtside calibrate --graph`). Since issue 29 a record says which (optional top-level ``skeleton``:
a human ``name``, the joint count, and a ``fingerprint`` of its names, parents and offsets, `skeleton_identity`)
and holds each sensor's strapping relative to its placement's nominal sensor frame (optional ``strap_wxyz``, the
quaternion of ``R_nominalᵀ R``), which is the same frame on every skeleton (a placement is defined on the
T-pose). So :func:`placements_from_calibration` uses a record made for this skeleton as it is, converts one made
for other joint frames (``R = R_nominal(this skeleton) · strap``), and refuses, in one line naming both skeletons,
only an older record without the strapping whose rotations do not fit these frames: the angle between the
measured and this skeleton's nominal rotation must then equal the correction the calibration reported.
"""
from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from engine.errors import MalformedFileError
from engine.mocap import quaternions as quat
from engine.mocap.orientation_calibration import OrientationCalibration
from engine.mocap.sensors import STANDARD_SENSORS, SensorPlacement
from engine.versioned_json import read_versioned_json

SCHEMA = "courtside.sensor_calibration"
SCHEMA_VERSION = 1
MAX_RECORD_SENSORS = 64  # far more than a body wears; 100 000 "sensors" is not a record (issue 30)
ORIENTATION_YAW, ORIENTATION_MOUNT = "orientation_yaw_rad", "orientation_mount_wxyz"  # optional, per sensor
STRAP = "strap_wxyz"  # optional, per sensor: the strapping relative to the placement's nominal sensor frame
SKELETON = "skeleton"  # optional, top level: the skeleton the rotations' joint frames belong to

log = logging.getLogger(__name__)


def _is_rotation(r: np.ndarray) -> bool:
    return r.shape == (3, 3) and bool(np.allclose(r @ r.T, np.eye(3), atol=1e-6)) and np.linalg.det(r) > 0


def _angle_deg(r: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0))))


def orientation_fields(yaw_rad: float | None, mount_wxyz: np.ndarray | None) -> dict:
    """A sensor entry's optional orientation pair as written (nothing when the sensor has none); the
    strapping's sign is fixed (w >= 0), one of the two equal quaternions."""
    if yaw_rad is None or mount_wxyz is None:
        return {}
    mount = np.asarray(mount_wxyz, float).reshape(4)
    return {ORIENTATION_YAW: float(yaw_rad), ORIENTATION_MOUNT: (mount if mount[0] >= 0 else -mount).tolist()}


def skeleton_identity(skeleton, name: str) -> dict:
    """``{"name", "joints", "fingerprint"}`` of a skeleton: `name` for people (e.g. the graph file's), the
    fingerprint (12 hex digits of a SHA-1 over the joint names, parents and offsets to 0.1 mm) for the check."""
    digest = hashlib.sha1()
    digest.update("\0".join(skeleton.names).encode())
    digest.update(np.asarray(skeleton.parents, np.int64).tobytes())
    digest.update(np.round(np.asarray(skeleton.offsets_m, float) * 1e4).astype(np.int64).tobytes())
    return {"name": str(name), "joints": int(skeleton.n_joints), "fingerprint": digest.hexdigest()[:12]}


def skeleton_text(identity: Mapping | None) -> str:
    """How a message names a skeleton identity (None: a record from before records named theirs)."""
    if not identity:
        return "an unnamed skeleton (a record from before issue 29: the shipped CMU one unless made otherwise)"
    return f"{identity['name']} ({identity['joints']} joints, {identity['fingerprint']})"


def read_skeleton_field(doc: Mapping) -> dict | None:
    """The record's ``skeleton`` identity, or None when it has none; ValueError when it is malformed."""
    value = doc.get(SKELETON)
    if value is None:
        return None
    if not (isinstance(value, Mapping) and isinstance(value.get("name"), str) and isinstance(value.get("joints"), int)
            and isinstance(value.get("fingerprint"), str)):
        raise ValueError(f"{SKELETON!r} must be an object with a name, a joint count and a fingerprint")
    return {"name": value["name"], "joints": value["joints"], "fingerprint": value["fingerprint"]}


def strap_field(strap_wxyz: np.ndarray | None) -> dict:
    """A sensor entry's optional strapping as written (nothing when unknown), sign fixed (w >= 0)."""
    if strap_wxyz is None:
        return {}
    strap = np.asarray(strap_wxyz, float).reshape(4)
    return {STRAP: (strap if strap[0] >= 0 else -strap).tolist()}


def read_strap_field(entry: Mapping) -> np.ndarray | None:
    """A sensor entry's strapping (4,), or None; ValueError when it is not a finite unit quaternion."""
    if entry.get(STRAP) is None:
        return None
    strap = np.asarray(entry[STRAP], float).reshape(4)
    if not np.isfinite(strap).all() or abs(np.linalg.norm(strap) - 1.0) > 1e-3:
        raise ValueError(f"{STRAP} is not a finite unit quaternion")
    return strap


def read_orientation_fields(entry: Mapping) -> tuple[float, np.ndarray] | None:
    """A sensor entry's orientation pair ``(yaw_rad, mount_wxyz (4,))``, or None when it has none. ValueError
    when only one of the two is there, or either is not finite, or the strapping is not a unit quaternion."""
    has = [entry.get(k) is not None for k in (ORIENTATION_YAW, ORIENTATION_MOUNT)]
    if not any(has):
        return None
    if not all(has):
        raise ValueError(f"{ORIENTATION_YAW} and {ORIENTATION_MOUNT} go together; only one is given")
    yaw = float(entry[ORIENTATION_YAW])
    mount = np.asarray(entry[ORIENTATION_MOUNT], float).reshape(4)
    if not (np.isfinite(yaw) and np.isfinite(mount).all()):
        raise ValueError("non-finite orientation calibration")
    if abs(yaw) > 2 * np.pi:  # the calibration writes an angle in [-pi, pi]; 1e300 is not a yaw
        raise ValueError(f"{ORIENTATION_YAW} {yaw!r} is not an angle in [-2 pi, 2 pi]")
    if abs(np.linalg.norm(mount) - 1.0) > 1e-3:
        raise ValueError(f"{ORIENTATION_MOUNT} is not a unit quaternion (norm {np.linalg.norm(mount):.4f})")
    return yaw, mount


def calibrated_placements(placements: list[SensorPlacement], rotations: Mapping[str, np.ndarray],
                          bias_g: Mapping[str, np.ndarray] | None = None) -> list[SensorPlacement]:
    """Copies of ``placements`` whose ``rotation`` (sensor -> joint frame) is replaced by ``rotations[name]``
    and, when given, whose ``bias_g`` (3,) is ``bias_g[name]``. Placements not named keep their nominal values;
    a name that is not among the placements is an error (it would otherwise be silently ignored)."""
    names = {p.name for p in placements}
    unknown = sorted((set(rotations) | set(bias_g or {})) - names)
    if unknown:
        raise ValueError(f"calibration for unknown sensor placement(s) {unknown}; placements: {sorted(names)}")
    out = []
    for p in placements:
        changes = {}
        if p.name in rotations:
            changes["rotation"] = np.asarray(rotations[p.name], float)
        if bias_g and p.name in bias_g:
            changes["bias_g"] = np.asarray(bias_g[p.name], float)
        out.append(replace(p, **changes) if changes else p)
    return out


@dataclass
class SensorCalibrationData:
    """What the engine uses of a sensor-calibration record, keyed by placement (segment) name.

    ``rotations``: sensor -> segment (3, 3). ``bias_along_gravity_g``: ``norm_error_g`` times the measured
    gravity direction (sensor frame) -- the only bias component one still pose observes (it also absorbs scale
    error), so it is offered, not applied by default. ``sensor_ids``: the live sensor on each segment.
    ``correction_deg``: angle between the measured and the nominal mounting, as the wizard computed it.
    ``failed``: segments whose sensor did not pass the wizard's checks. ``orientation``: segment -> (yaw rad,
    strapping (4,)) of the sensors whose orientation was calibrated (`orientation_calibration` turns it into the
    engine's `OrientationCalibration`)."""

    path: Path
    rotations: dict[str, np.ndarray] = field(default_factory=dict)
    bias_along_gravity_g: dict[str, np.ndarray] = field(default_factory=dict)
    sensor_ids: dict[str, str] = field(default_factory=dict)
    correction_deg: dict[str, float] = field(default_factory=dict)
    failed: list[str] = field(default_factory=list)
    orientation: dict[str, tuple[float, np.ndarray]] = field(default_factory=dict)
    straps: dict[str, np.ndarray] = field(default_factory=dict)  # segment -> strapping (3, 3), records that hold it
    skeleton: dict | None = None  # `skeleton_identity` of the record's joint frames, records that say it

    def fingerprint(self) -> str:
        """Stable text of the rotations (and nothing else), for cache keys."""
        return json.dumps({k: np.round(v, 6).tolist() for k, v in sorted(self.rotations.items())})

    def orientation_calibration(self, sensor_names: Sequence[str]) -> OrientationCalibration | None:
        """The orientation calibration of the worn ``sensor_names`` (segments), in that order, or None -- said in a
        log line -- unless every one of them has one: the engine poses segments with their yaw relative to the
        pelvis only when all are calibrated (a segment whose earth-frame yaw is unknown would be turned by it),
        and with tilt alone otherwise."""
        names = list(sensor_names)
        missing = [n for n in names if n not in self.orientation]
        if missing:
            if len(missing) < len(names):
                log.info("%s: no orientation calibration for %s (the sensor streamed no orientation during the "
                         "still capture): worn segments posed by tilt only", self.path, ", ".join(missing))
            else:
                log.info("%s: no orientation calibration in the record: worn segments posed by tilt only", self.path)
            return None
        return OrientationCalibration(np.array([self.orientation[n][0] for n in names]),
                                      np.stack([self.orientation[n][1] for n in names]))


def read_calibration_record(path: str | Path) -> dict:
    """The JSON document of a ``courtside.sensor_calibration`` record, checked: schema and version, a non-empty
    ``sensors`` object, every entry's segment, proper 3x3 rotation, gravity (3,), finite numbers, the optional
    orientation pair (`read_orientation_fields`), one sensor per segment. The one check of the format: the engine
    (`load_sensor_calibration`) and the gateway (``gateway.calibration.CalibrationRecord.load``) both read records
    through it. Bad files raise MalformedFileError naming the file and the problem."""
    path = Path(path)
    doc = read_versioned_json(path, SCHEMA, SCHEMA_VERSION, "a sensor calibration record",
                              lambda p, problem: MalformedFileError(p, None, problem))
    sensors = doc.get("sensors")
    if not isinstance(sensors, dict) or not sensors:
        raise MalformedFileError(path, None, "no sensors in the record")
    if len(sensors) > MAX_RECORD_SENSORS:
        raise MalformedFileError(path, None, f"{len(sensors)} sensors: more than the {MAX_RECORD_SENSORS} a body "
                                             "can wear (not a calibration record)")
    try:
        read_skeleton_field(doc)
    except ValueError as exc:
        raise MalformedFileError(path, None, str(exc)) from None
    if "passed" in doc and not isinstance(doc["passed"], bool):  # "no" would count as passed
        raise MalformedFileError(path, None, f"'passed' must be true or false, got {doc.get('passed')!r}")
    segments: dict[str, str] = {}
    for sid, entry in sensors.items():
        try:
            segment = str(entry["segment"])
            rotation = np.asarray(entry["rotation"], float)
            gravity = np.asarray(entry["gravity_sensor_g"], float).reshape(3)
            numbers = [float(entry["norm_error_g"]), float(entry["correction_deg"])]
            if not isinstance(entry["passed"], bool):  # "no" would count as passed
                raise ValueError(f"'passed' must be true or false, got {entry['passed']!r}")
            read_orientation_fields(entry)
            read_strap_field(entry)
        except (KeyError, TypeError, ValueError) as exc:
            raise MalformedFileError(path, None, f"sensor {sid!r}: bad entry ({exc!r})") from None
        if not (np.all(np.isfinite(rotation)) and np.all(np.isfinite(gravity)) and np.all(np.isfinite(numbers))):
            raise MalformedFileError(path, None, f"sensor {sid!r}: non-finite numbers")
        if not _is_rotation(rotation):
            raise MalformedFileError(path, None, f"sensor {sid!r}: rotation is not a proper 3x3 rotation")
        if segment in segments:
            raise MalformedFileError(path, None, f"two sensors on segment {segment!r}: {segments[segment]!r} and {sid!r}")
        segments[segment] = str(sid)
    if not set(segments) & set(STANDARD_SENSORS):
        raise MalformedFileError(path, None, f"no sensor on a known segment (the record names {sorted(segments)}; "
                                             f"known: {', '.join(STANDARD_SENSORS)}): it would calibrate nothing")
    return doc


def load_sensor_calibration(path: str | Path) -> SensorCalibrationData:
    """What the engine uses of a ``courtside.sensor_calibration`` record (`read_calibration_record`), read
    without the gateway."""
    path = Path(path)
    doc = read_calibration_record(path)
    out = SensorCalibrationData(path, skeleton=read_skeleton_field(doc))
    for sid, entry in doc["sensors"].items():
        segment = str(entry["segment"])
        gravity = np.asarray(entry["gravity_sensor_g"], float).reshape(3)
        out.rotations[segment] = np.asarray(entry["rotation"], float)
        out.bias_along_gravity_g[segment] = float(entry["norm_error_g"]) * gravity / max(np.linalg.norm(gravity), 1e-12)
        out.sensor_ids[segment] = str(sid)
        out.correction_deg[segment] = float(entry["correction_deg"])
        if not bool(entry["passed"]):
            out.failed.append(segment)
        orientation = read_orientation_fields(entry)
        if orientation is not None:
            out.orientation[segment] = orientation
        strap = read_strap_field(entry)
        if strap is not None:
            out.straps[segment] = quat.to_matrix(strap)
    return out


def placements_from_calibration(placements: list[SensorPlacement], calibration: SensorCalibrationData,
                                with_bias: bool = False, frame_tolerance_deg: float = 5.0,
                                skeleton_id: Mapping | None = None) -> list[SensorPlacement]:
    """``calibrated_placements`` from a loaded record, for the placements the record covers (others stay
    nominal; record segments not among ``placements`` are ignored -- the graph simply does not use them).

    ``skeleton_id`` (`skeleton_identity` of the placements' skeleton, when the caller knows it): a record made
    for that skeleton is used as it is; one made for other joint frames is converted through each sensor's
    strapping (module docstring). A record without the strapping must fit these frames: for every sensor, the
    angle between the measured rotation and *these* placements' nominal rotation must match the correction it
    reports within ``frame_tolerance_deg``; MalformedFileError naming both skeletons otherwise."""
    nominal = {p.name: p.rotation for p in placements}
    used = [s for s in calibration.rotations if s in nominal]
    same = bool(skeleton_id and calibration.skeleton
                and calibration.skeleton["fingerprint"] == skeleton_id["fingerprint"])
    other = bool(skeleton_id and calibration.skeleton) and not same  # the record names other joint frames
    rotations, converted = {}, False
    for seg in used:
        angle = _angle_deg(calibration.rotations[seg] @ nominal[seg].T)
        fits = abs(angle - calibration.correction_deg[seg]) <= frame_tolerance_deg
        if not same and seg in calibration.straps and (other or not fits):
            rotations[seg], converted = nominal[seg] @ calibration.straps[seg], True
            continue
        if not same and not fits:
            target = skeleton_text(skeleton_id) if skeleton_id else "this one"
            raise MalformedFileError(
                calibration.path, None, f"the record was made for another skeleton's joint frames, "
                f"{skeleton_text(calibration.skeleton)}, not {target}, and holds no strapping to convert it (sensor on "
                f"{seg!r}: {angle:.0f} deg from this skeleton's nominal mounting, corrected "
                f"{calibration.correction_deg[seg]:.0f} deg): calibrate again with `courtside calibrate --graph GRAPH`")
        rotations[seg] = calibration.rotations[seg]
    if converted:
        log.info("%s: made for %s: converted to %s through each sensor's strapping", calibration.path,
                 skeleton_text(calibration.skeleton), skeleton_text(skeleton_id) if skeleton_id else "these frames")
    bias = {s: calibration.bias_along_gravity_g[s] for s in used} if with_bias else None
    return calibrated_placements(placements, rotations, bias)


def reading_corrections(placements: list[SensorPlacement], calibration: SensorCalibrationData,
                        skeleton_id: Mapping | None = None) -> dict[str, np.ndarray]:
    """Per calibrated placement, the rotation ``C = R_nominalᵀ R_measured`` that turns the real sensor's readings
    into what the nominally mounted virtual sensor reads (``a_nominal = C a_real``), so a take can be synthesised
    on a graph built with the nominal mounting instead of rebuilding the graph. Same frame check (and conversion)
    as :func:`placements_from_calibration`, for the skeleton `skeleton_id` names."""
    measured = {p.name: p.rotation for p in placements_from_calibration(placements, calibration,
                                                                       skeleton_id=skeleton_id)}
    return {p.name: p.rotation.T @ measured[p.name] for p in placements if p.name in calibration.rotations}
