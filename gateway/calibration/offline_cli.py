"""`courtside calibrate take.npz -o take.calibration.json`: sensor-to-segment rotations from a recorded take
(gateway.calibration.recording), written as the same record the live wizard saves."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from engine.errors import CourtsideError, MalformedFileError
from engine.graph.input_checks import open_npz
from engine.mocap import STANDARD_SENSORS
from gateway.calibration.recording import (SECOND_POSES, RecordingCalibrationConfig, calibrate_recording,
                                           standard_segment_poses)


def _read_take(path: Path) -> tuple[np.ndarray, float, list[str], list[str]]:
    """acc_g (T, S, 3), fps, placement names, sensor ids (source labels) of a synthesis-input take."""
    with open_npz(path) as data:
        missing = [k for k in ("acc_g", "fps", "sensor_names") if k not in data.files]
        if missing:
            raise MalformedFileError(path, None, f"missing {missing}: calibrate reads a take written by "
                                                 "`courtside import-imu` (or any synthesis-input .npz with sensor_names)")
        acc = np.asarray(data["acc_g"], float)
        names = [str(n) for n in data["sensor_names"]]
        labels = [str(n) for n in data["source_labels"]] if "source_labels" in data.files else names
        fps = float(data["fps"])
    if acc.ndim != 3 or acc.shape[1:] != (len(names), 3):
        raise MalformedFileError(path, None, f"acc_g has shape {acc.shape}, expected (T, {len(names)}, 3)")
    unknown = [n for n in names if n not in STANDARD_SENSORS]
    if unknown:
        raise MalformedFileError(path, None, f"sensor names {unknown} are not standard placements")
    return acc, fps, names, labels


def _windows(texts: list[str] | None) -> dict[str, tuple[float, float]]:
    out: dict[str, tuple[float, float]] = {}
    for text in texts or []:
        try:
            pose, span = text.split("@", 1)
            start, end = (float(x) for x in span.split(":", 1))
        except ValueError:
            raise CourtsideError(f"--second-pose {text!r}: expected POSE@START:END (seconds), e.g. tpose@12:14") \
                from None
        if pose not in SECOND_POSES:
            raise CourtsideError(f"--second-pose: unknown pose {pose!r}; known: {', '.join(SECOND_POSES)}")
        out[pose] = (start, end)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="courtside calibrate", description=__doc__)
    p.add_argument("take", help="take .npz from `courtside import-imu`")
    p.add_argument("-o", "--output", required=True, help="record .calibration.json (raw still samples go beside it)")
    p.add_argument("--second-pose", metavar="POSE@START:END", action="append",
                   help="a second still pose held in the take (fixes the heading with sign): tpose@12:14 for the "
                        "arms, bow@20:22 (a forward bow from the hips) for pelvis and chest; repeatable")
    p.add_argument("--max-std", type=float, default=RecordingCalibrationConfig.max_std_g,
                   help="windows stiller than this (g) count as quasi-static")
    p.add_argument("--subject", default="")
    args = p.parse_args(sys.argv[1:] if argv is None else argv)
    path = Path(args.take)
    acc, fps, names, labels = _read_take(path)
    windows = _windows(args.second_pose)
    config = RecordingCalibrationConfig(max_std_g=args.max_std)
    try:
        record = calibrate_recording(acc, fps, labels, names, standard_segment_poses(names, tuple(windows)), config,
                                     windows, args.subject, path.stem)
    except ValueError as exc:
        raise CourtsideError(f"{path}: {exc}") from None
    try:
        record.save(args.output)
    except OSError as exc:
        raise CourtsideError(f"{args.output}: cannot write the record ({exc.strerror or exc})") from None
    for sid, s in record.sensors.items():
        for reason in s.reasons:
            print(f"calibrate: warning: {sid} ({s.segment}): {reason}", file=sys.stderr)
    print(json.dumps({"output": args.output, "quality": record.quality_score, "grade": record.grade,
                      "passed": record.passed,
                      "sensors": {sid: {"segment": s.segment, "correction_deg": round(s.correction_deg, 1),
                                        "quality": round(s.quality, 2)} for sid, s in record.sensors.items()}}))
    return 0
