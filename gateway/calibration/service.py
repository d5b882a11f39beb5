"""Calibration hook for the gateway daemon: request actions -> :class:`CalibrationWizard`, samples in.

Contract (docs/gateway.md "Hooks"): ``handle(action, args) -> result``, ``state() -> dict`` and
``on_samples(station, sensor, t_host_s, acc_g, quat_wxyz=None)`` (orientations of a sensor that streams them).
Sensor ids in the wizard are ``"<station>/<sensor>"``.
Reader threads push samples while client threads send actions, so one lock serialises both.

``save`` writes ``<records_dir>/<name>.calibration.json`` (+ ``.npz``) and nothing else: the client names the
record, never the path (issue 12: a client-chosen path overwrote an arbitrary file). Names are checked by
`gateway.names.check_name`; an existing record is never overwritten.

Actions (``GatewayClient.calibration(action, **args)``):

=========  =====================================  ==============================================
action     args                                   result
=========  =====================================  ==============================================
state      -                                      the snapshot
assign     ``sensor`` (id), ``segment``           the snapshot
unassign   ``sensor``                             the snapshot
confirm    -                                      ``{"accepted": bool, "state": snapshot}``
redo       ``step``                               the snapshot
save       ``name``, ``subject``, ``take``        ``{"json": path, "npz": path, "quality": {...}}``
reset      -                                      the snapshot of a fresh wizard (same segments)
=========  =====================================  ==============================================
"""
from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import numpy as np

from gateway.calibration.pose import pose_rotations
from gateway.calibration.wizard import CalibrationWizard, SegmentSpec, WizardConfig, segment_specs_from_placements
from gateway.names import BadNameError, check_name
from gateway.server import RequestError

RECORD_SUFFIX = ".calibration.json"


class CalibrationService:
    """Thread-safe wrapper of a wizard for the gateway."""

    def __init__(self, segments: dict[str, SegmentSpec], config: WizardConfig = WizardConfig(),
                 pose: str | None = None, records_dir: str | Path | None = None) -> None:
        self.records_dir = Path(records_dir) if records_dir is not None else None
        self._segments = segments
        self._config = config
        self._pose = pose
        self._lock = threading.Lock()
        self.wizard = CalibrationWizard(segments, config, pose)

    skeleton_id: dict[str, Any] | None = None  # the skeleton whose joint frames the records' rotations are in

    @classmethod
    def standard(cls, sensor_names: tuple[str, ...] | None = None, config: WizardConfig = WizardConfig(),
                 pose: str = "npose", records_dir: str | Path | None = None, skeleton: Any = None,
                 skeleton_name: str = "the shipped CMU skeleton") -> "CalibrationService":
        """Segments = the engine's standard sensor placements (default: the six seed-000 sensors) on
        ``skeleton`` (default: the shipped CMU skeleton; a loaded graph's skeleton makes records for that graph,
        any skeleton works, raw Bandai included), i.e. exactly the mounting the engine's virtual sensors assume,
        calibrated in ``pose``: ``"npose"`` (default: the reference N-pose of
        ``gateway.calibration.pose.reference_npose``, arms straight down, palms in, legs straight) or ``"tpose"``
        (the skeleton's zero pose: arms out). Saved records name the skeleton (``skeleton_name``)."""
        from engine.mocap import SEED000_SENSORS, load_clip, sample_clips, standard_placements
        from engine.mocap.calibrated import skeleton_identity

        skeleton = skeleton if skeleton is not None else load_clip(sample_clips()["16_01"]).skeleton
        placements = standard_placements(skeleton, sensor_names or SEED000_SENSORS)
        specs = segment_specs_from_placements(placements, pose_rotations=pose_rotations(skeleton, pose))
        service = cls(specs, config, pose, records_dir)
        service.skeleton_id = skeleton_identity(skeleton, skeleton_name)
        return service

    def on_samples(self, station: str, sensor: int | str, t_host_s: np.ndarray, acc_g: np.ndarray,
                   quat_wxyz: np.ndarray | None = None) -> None:
        with self._lock:
            self.wizard.push(f"{station}/{sensor}", t_host_s, acc_g, quat_wxyz)

    def state(self) -> dict[str, Any]:
        with self._lock:
            return self.wizard.snapshot()

    def handle(self, action: str, args: dict[str, Any]) -> Any:
        """Run one action; operator mistakes come back to the client as a clean ``RequestError``."""
        try:
            return self._handle(action, args)
        except KeyError as exc:
            raise RequestError(f"calibration {action!r} needs argument {exc.args[0]!r}") from None
        except BadNameError as exc:
            raise RequestError(f"calibration {action!r}: {exc}") from None
        except (ValueError, RuntimeError, OSError) as exc:
            raise RequestError(f"calibration {action!r}: {exc}") from None

    def _handle(self, action: str, args: dict[str, Any]) -> Any:
        with self._lock:
            wiz = self.wizard
            if action == "state":
                pass
            elif action == "assign":
                wiz.assign(str(args["sensor"]), str(args["segment"]))
            elif action == "unassign":
                wiz.unassign(str(args["sensor"]))
            elif action == "confirm":
                accepted = wiz.confirm()
                return {"accepted": accepted, "state": wiz.snapshot()}
            elif action == "redo":
                wiz.redo(str(args["step"]))
            elif action == "save":
                path = self._record_path(args)
                record = wiz.record(subject=str(args.get("subject", "")), take=str(args.get("take", "")))
                record.skeleton = self.skeleton_id
                path.parent.mkdir(parents=True, exist_ok=True)
                npz = record.save(path)
                return {"json": str(path), "npz": str(npz), "quality": wiz.quality()}
            elif action == "reset":
                self.wizard = CalibrationWizard(self._segments, self._config, self._pose)
            else:
                raise ValueError(f"unknown calibration action {action!r}; known: state, assign, unassign, "
                                 "confirm, redo, save, reset")
            return self.wizard.snapshot()

    def _record_path(self, args: dict[str, Any]) -> Path:
        """``<records_dir>/<name>.calibration.json``, refusing client paths, bad names and existing records."""
        if "path" in args:
            raise ValueError("save takes a record 'name', not a path: records go to the gateway's records directory")
        if self.records_dir is None:
            raise ValueError("this gateway has no calibration records directory configured")
        name = check_name(args["name"], "record name")
        path = self.records_dir / f"{name}{RECORD_SUFFIX}"
        if path.exists() or path.with_suffix(".npz").exists():
            raise ValueError(f"record {name!r} already exists in {self.records_dir}; choose another name")
        return path
