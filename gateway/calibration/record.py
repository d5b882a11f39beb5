"""Versioned sensor-calibration record: JSON with the take, raw step samples in an ``.npz`` beside it.

Why keep raw samples: calibration can then be recomputed offline (different thresholds, a better yaw method)
without re-recording the subject - the MVNX/XDF "never throw raw data away" practice.
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from engine.array_checks import READ_ERRORS
from engine.atomic_write import atomic_write
from engine.errors import MalformedFileError
from engine.mocap import quaternions
# the format is the engine's (issue 19): one reader, one definition of the optional orientation fields
from engine.mocap.calibrated import (ORIENTATION_MOUNT, ORIENTATION_YAW, SCHEMA, SCHEMA_VERSION, SKELETON, STRAP,
                                     orientation_fields, read_calibration_record, read_orientation_fields,
                                     read_skeleton_field, read_strap_field, strap_field)
from gateway.calibration.errors import CalibrationRecordError

RAW_KINDS = ("t_s", "acc_g", "quat_wxyz")  # the raw samples of one sensor in one step, in tuple order (the last
# only for a sensor that streamed its orientation)


def raw_samples_path(record_path: str | Path) -> Path:
    """Where a record's raw samples go: beside it, same stem, ``.npz`` (so ``calibrate t.npz -o t.json`` would
    write over its own take: the CLI refuses that before it starts)."""
    return Path(record_path).with_suffix(".npz")


@dataclass
class SensorCalibration:
    """Result for one sensor. ``rotation`` (3, 3): sensor axes -> segment frame (engine ``SensorPlacement``).
    ``orientation_yaw_rad`` / ``orientation_mount_wxyz`` (4,): for a sensor that streamed its orientation during
    the still capture, its earth frame's yaw and its strapping (`engine.mocap.OrientationCalibration` of one
    sensor); None for an accelerometer-only sensor (and in records written before them). ``strap_wxyz`` (4,):
    the strapping relative to the placement's nominal sensor frame (``R_nominalᵀ rotation``), what converts the
    record to another skeleton's joint frames (`engine.mocap.calibrated`); None in records written before it."""

    sensor_id: str
    segment: str
    rotation: np.ndarray
    gravity_sensor_g: np.ndarray
    norm_error_g: float
    capture_std_g: float
    correction_deg: float
    quality: float
    passed: bool
    reasons: list[str] = field(default_factory=list)
    orientation_yaw_rad: float | None = None
    orientation_mount_wxyz: np.ndarray | None = None
    strap_wxyz: np.ndarray | None = None

    def to_dict(self) -> dict[str, Any]:
        out = {k: v for k, v in asdict(self).items() if k not in (ORIENTATION_YAW, ORIENTATION_MOUNT, STRAP)}
        out["rotation"] = np.asarray(self.rotation).tolist()
        q = quaternions.from_matrix(self.rotation)
        out["rotation_wxyz"] = (q if q[0] >= 0 else -q).tolist()  # w >= 0: one of the two equal quaternions
        out["gravity_sensor_g"] = np.asarray(self.gravity_sensor_g).tolist()
        return {**out, **orientation_fields(self.orientation_yaw_rad, self.orientation_mount_wxyz),
                **strap_field(self.strap_wxyz)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "SensorCalibration":
        fields = {k: data[k] for k in cls.__dataclass_fields__ if k not in (ORIENTATION_YAW, ORIENTATION_MOUNT, STRAP)}
        fields[STRAP] = read_strap_field(data)
        fields["rotation"] = np.asarray(fields["rotation"], float)
        fields["gravity_sensor_g"] = np.asarray(fields["gravity_sensor_g"], float)
        orientation = read_orientation_fields(data)
        if orientation is not None:
            fields[ORIENTATION_YAW], fields[ORIENTATION_MOUNT] = orientation
        return cls(**fields)


@dataclass
class CalibrationRecord:
    """A finished calibration. ``raw``: step -> sensor id -> ``(t_s (N,), acc_g (N, 3))``, with a third array
    ``quat_wxyz`` (N, 4) for a sensor whose orientations went into it. ``skeleton``: the identity of the skeleton
    whose joint frames the rotations are in (`engine.mocap.calibrated.skeleton_identity`; None: not said)."""

    sensors: dict[str, SensorCalibration]
    quality_score: float
    grade: str
    passed: bool
    tap: dict[str, Any] | None = None
    subject: str = ""
    take: str = ""
    created_utc: str = ""
    config: dict[str, Any] = field(default_factory=dict)
    raw: dict[str, dict[str, tuple[np.ndarray, ...]]] = field(default_factory=dict)
    skeleton: dict[str, Any] | None = None

    def rotation(self, sensor_id: str) -> np.ndarray:
        """Sensor -> segment rotation (3, 3) for ``engine.mocap.SensorPlacement(..., rotation=...)``."""
        return self.sensors[sensor_id].rotation

    def save(self, path: str | Path) -> Path:
        """Write ``path`` (JSON) and the raw samples beside it (`raw_samples_path`); returns the npz path. Each
        file is written whole or not at all (`engine.atomic_write`)."""
        path = Path(path)
        npz_path = raw_samples_path(path)
        arrays = {}
        for step, per_sensor in self.raw.items():
            for sensor_id, samples in per_sensor.items():
                for kind, values in zip(RAW_KINDS, samples):
                    arrays[f"{step}/{sensor_id}/{kind}"] = np.asarray(values)
        atomic_write(npz_path, lambda fh: np.savez_compressed(fh, **arrays))
        doc = {
            "schema": SCHEMA, "schema_version": SCHEMA_VERSION, "created_utc": self.created_utc,
            "subject": self.subject, "take": self.take, "quality_score": self.quality_score, "grade": self.grade,
            "passed": self.passed, "tap": self.tap, "config": self.config,
            "sensors": {sid: s.to_dict() for sid, s in self.sensors.items()},
            "raw_samples_file": npz_path.name, **({SKELETON: self.skeleton} if self.skeleton else {}),
        }
        atomic_write(path, lambda fh: fh.write(json.dumps(doc, indent=2).encode()))
        return npz_path

    @classmethod
    def load(cls, path: str | Path, with_raw: bool = True) -> "CalibrationRecord":
        """Read a record (and its raw samples); CalibrationRecordError names the file and the problem."""
        path = Path(path)
        try:  # the format's one check, shared with the engine's reader
            doc = read_calibration_record(path)
        except MalformedFileError as exc:
            raise CalibrationRecordError(exc.path, exc.problem) from None
        try:
            sensors = {sid: SensorCalibration.from_dict(s) for sid, s in doc["sensors"].items()}
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationRecordError(path, f"bad sensor entry: {exc!r}") from None
        raw: dict[str, dict[str, tuple[np.ndarray, ...]]] = {}
        if with_raw:
            npz_path = path.parent / doc.get("raw_samples_file", path.with_suffix(".npz").name)
            try:
                with np.load(npz_path) as data:
                    for key in data.files:
                        step, rest = key.split("/", 1)  # sensor ids may contain "/" themselves
                        sensor_id, kind = rest.rsplit("/", 1)
                        if kind == "t_s":
                            raw.setdefault(step, {})[sensor_id] = tuple(
                                data[f"{step}/{sensor_id}/{k}"] for k in RAW_KINDS
                                if k != "quat_wxyz" or f"{step}/{sensor_id}/{k}" in data.files)
            except (*READ_ERRORS, KeyError) as exc:
                raise CalibrationRecordError(npz_path, f"raw samples unreadable: {exc}") from None
        return cls(
            sensors=sensors, quality_score=float(doc["quality_score"]), grade=str(doc["grade"]),
            passed=bool(doc["passed"]), tap=doc.get("tap"), subject=doc.get("subject", ""), take=doc.get("take", ""),
            created_utc=doc.get("created_utc", ""), config=doc.get("config", {}), raw=raw,
            skeleton=read_skeleton_field(doc),
        )
