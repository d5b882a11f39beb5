"""`courtside calibrate take.npz -o take.calibration.json`: sensor-to-segment rotations from a recorded take
(gateway.calibration.recording), written as the same record the live wizard saves.

The take is an `import-imu` file, or the gateway's own recording (`courtside gateway export --npz`) with
``--sensor-map STATION/SENSOR=PLACEMENT``: then the record's sensor ids are the live ``station/sensor`` keys, so
`courtside console --calibration` reads each segment from that live sensor (devices bought off the shelf are one
station each, and no station holds all the worn sensors). A take with orientations (``quat_wxyz``: an
`import-imu` file from devices that report one, or a recording of orientation-capable stations) also gets each
sensor's yaw and strapping calibrated: any strapping, from the pose the take starts with (found
in its first still stretch: N-pose, T-pose or an A-pose of any arm angle; or declared with --pose), or from the
motion alone (--pose none, needs --graph).

``--graph GRAPH.npz`` calibrates for that graph: the poses are built on its skeleton, the record's rotations are
in its joint frames and name it (so `courtside synthesize --graph GRAPH --calibration REC` takes the record as it
is), and its database fits what one held pose cannot show: each orientation sensor's strap twist about the pose's
vertical, an A-pose's arm angle under unknown straps, and every angle of a calibration from the motion
(engine/mocap/take_calibration.py)."""
from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.atomic_write import refuse_overwriting_inputs
from engine.errors import ArgumentParser, CourtsideError, MalformedFileError, check_output_dir
from engine.export_format import recorded_sensors
from engine.graph.input_checks import check_take_file, open_npz, parse_sensor_map
from engine.mocap import STANDARD_SENSORS
from gateway.calibration.record import raw_samples_path
from engine.mocap.take_calibration import NO_TWIST_NOTE, NORTHS, MotionPrior, PoseSpec
from gateway.calibration.recording import (SECOND_POSES, RecordingCalibrationConfig, TakeStart, calibrate_recording,
                                           standard_segment_poses)


EXPORT_RATE_HZ = 50.0  # a gateway recording is brought to this frame clock (0.5 s windows, gait below 6 Hz)
# import-imu formats whose orientations share one earth frame by default, and why (said with the decision)
ONE_NORTH_FORMATS = {"xsens": "an Xsens export: its filters reference every sensor's heading to local magnetic north "
                              "(Xsens DOT user manual, 4.1.2; MTw and MVN likewise) unless a heading-free profile "
                              "was set"}


@dataclass
class CalibrationTake:
    """What calibration reads of a take: ``acc_g`` (T, S, 3) at ``fps``, each column's placement ``names`` and
    sensor id (``labels``), and ``quat_wxyz`` (T, S, 4) when the take has orientations (NaN where a sensor has
    none)."""

    acc_g: np.ndarray
    fps: float
    names: list[str]
    labels: list[str]
    quat_wxyz: np.ndarray | None = None
    one_north_source: str = ""  # why the file's orientations share one north, when its format says so ("": unknown)


def _read_gateway_export(path: Path, sensor_map: dict[str, str]) -> CalibrationTake:
    """A gateway export on one frame clock by the console's own sample -> frame path
    (`engine.graph.inputs.read_take`), sensor ids = the live keys. Accelerations of frames a dropout touched are
    filled linearly from their neighbours: calibration averages windows, and a NaN would void a whole window (an
    orientation stays NaN there: windows with one are not used for it)."""
    from engine.graph.inputs import read_take

    placements = list(sensor_map.values())
    take = read_take(path, placements, EXPORT_RATE_HZ, sensor_map)
    acc = np.array(take.obs.acc_g, float)
    bad = ~np.isfinite(acc).all(axis=(1, 2))
    if bad.all():
        raise MalformedFileError(path, None, "no frame has every mapped sensor's samples")
    if bad.any():
        good = np.flatnonzero(~bad)
        for k in range(acc.shape[1]):
            for axis in range(3):
                acc[bad, k, axis] = np.interp(np.flatnonzero(bad), good, acc[good, k, axis])
    names = [placements[i] for i in take.obs.sensor_indices]
    quat = take.obs.quat_wxyz
    streamed = quat is not None and bool(np.isfinite(quat).any())  # NaN throughout: no station streamed one
    return CalibrationTake(acc, EXPORT_RATE_HZ, names, list(take.stream_keys), quat if streamed else None)


def _read_take(path: Path, sensor_map: dict[str, str] | None = None) -> CalibrationTake:
    """A synthesis-input take (sensor ids = its source labels), or a gateway export when ``sensor_map`` is
    given."""
    with open_npz(path) as data:
        is_export = "acc_g" not in data.files and bool(recorded_sensors(data.files))  # engine.export_format
    if is_export:
        if not sensor_map:
            raise MalformedFileError(path, None, "a gateway recording: say which sensor is worn where with "
                                                 "--sensor-map STATION/SENSOR=PLACEMENT ...")
        return _read_gateway_export(path, sensor_map)
    if sensor_map:
        raise MalformedFileError(path, None, "--sensor-map is for gateway recordings; this take names its sensors")
    with open_npz(path) as data:
        missing = [k for k in ("acc_g", "fps", "sensor_names") if k not in data.files]
        if missing:
            raise MalformedFileError(path, None, f"missing {missing}: calibrate reads a take written by "
                                                 "`courtside import-imu` (or any synthesis-input .npz with sensor_names)")
        check_take_file(path, data)  # synthesize's own take check: past here shapes, rate and values are sound
        acc = np.asarray(data["acc_g"], float)
        names = [str(n) for n in data["sensor_names"]]
        labels = [str(n) for n in data["source_labels"]] if "source_labels" in data.files else names
        fps = float(data["fps"])
        quat = np.asarray(data["quat_wxyz"], float) if "quat_wxyz" in data.files else None
        source_format = _import_format(data)
    unknown = [n for n in names if n not in STANDARD_SENSORS]
    if unknown:
        raise MalformedFileError(path, None, f"sensor names {unknown} are not standard placements")
    one_north = ONE_NORTH_FORMATS.get(source_format, "") if quat is not None else ""
    return CalibrationTake(acc, fps, names, labels, quat, one_north)


def _import_format(data) -> str:
    """The `import-imu` format a take came from (its ``import_report``), "" when it does not say."""
    if "import_report" not in data.files:
        return ""
    try:
        return str(json.loads(str(data["import_report"])).get("format", ""))
    except (ValueError, AttributeError):
        return ""


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


def _take_start(pose_text: str, graph_path: str | None, north: str) -> TakeStart:
    """--pose, --graph and --north as a `TakeStart`: the graph's skeleton (named after its file) and database, or
    the shipped CMU skeleton and none."""
    from engine.mocap import load_clip, sample_clips
    from engine.mocap.calibrated import skeleton_identity

    try:
        pose = PoseSpec.parse(pose_text)
    except ValueError as exc:
        raise CourtsideError(f"--pose: {exc}") from None
    if graph_path is None:
        if pose.name == "none":
            raise CourtsideError("--pose none calibrates from the motion against a database: give --graph GRAPH.npz")
        skeleton = load_clip(sample_clips()["16_01"]).skeleton
        return TakeStart(pose, skeleton, skeleton_identity(skeleton, "the shipped CMU skeleton"), north=north)
    from engine.graph.graph import MotionGraph

    graph = MotionGraph.load(graph_path)  # an unreadable graph is one MalformedFileError line
    if graph.skeleton is None:
        raise MalformedFileError(graph_path, None, "the graph holds no skeleton to calibrate for (rebuild it with "
                                                   "build-graph)")
    return TakeStart(pose, graph.skeleton, skeleton_identity(graph.skeleton, Path(graph_path).name),
                     MotionPrior.from_graph(graph), north)


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="courtside calibrate", description=__doc__)
    p.add_argument("take", help="take .npz from `courtside import-imu`, or a gateway recording exported with "
                                "`courtside gateway export --npz` (with --sensor-map)")
    p.add_argument("--sensor-map", nargs="+", default=None, metavar="STATION/SENSOR=PLACEMENT",
                   help="gateway recordings: which recorded sensor is worn where (standard placements: "
                        f"{', '.join(STANDARD_SENSORS)}); the record names the live sensors")
    p.add_argument("-o", "--output", required=True, help="record .calibration.json (raw still samples go beside it)")
    p.add_argument("--second-pose", metavar="POSE@START:END", action="append",
                   help="a second still pose held in the take (fixes the heading with sign): tpose@12:14 for the "
                        "arms, bow@20:22 (a forward bow from the hips) for pelvis and chest, sit@30:32 (sitting on "
                        "the floor, legs straight out in front, kneecaps up) for the shanks; repeatable")
    p.add_argument("--max-std", type=float, default=RecordingCalibrationConfig.max_std_g,
                   help="windows stiller than this (g) count as quasi-static")
    p.add_argument("--graph", metavar="GRAPH.npz",
                   help="calibrate for this motion graph: its skeleton's joint frames and poses, its database for the "
                        "strap twists, the arm angle and --pose none (default: the shipped CMU skeleton, no database)")
    p.add_argument("--pose", metavar="npose|tpose|apose[:DEG][@START:END]|none", default="apose",
                   help="takes with orientations: the pose the take starts with (palms facing the body), held "
                        "from START to END s (default: found, an A-pose of any arm angle, DEG out from hanging: "
                        "0 = N-pose, 90 = T-pose arms, in the first still stretch); none: no held pose, calibrate "
                        "from the motion (needs --graph)")
    p.add_argument("--north", choices=NORTHS, default="auto",
                   help="takes with orientations: do the sensors share one earth frame? shared: a magnetometer-aided "
                        "(9-axis) filter, as Xsens MTw/DOT report by default: one held pose then fixes every strap "
                        "but the athlete's heading, found from the motion; own: each sensor's north is its own "
                        "(6-axis filters, where the device booted); auto (default): one north for an Xsens export "
                        "(import-imu --format xsens: magnetic north), else solved each, one north taken "
                        "when they agree (--pose none: when the segments turn with the pelvis as in the database "
                        "and the one-north solve fits nearly as well; it can take one north for 6-axis sensors, so "
                        "pass own for them: 9.1 against 10.7 cm in the 6-axis sessions from motion)")
    p.add_argument("--subject", default="", help="who wore the sensors, written into the record")
    args = p.parse_args(sys.argv[1:] if argv is None else argv)
    path = Path(args.take)
    check_output_dir(args.output)  # refused before the calibration runs, not after it
    refuse_overwriting_inputs([args.output], [path])
    refuse_overwriting_inputs([raw_samples_path(args.output)], [path], f"the raw samples of -o {args.output}")
    take = _read_take(path, parse_sensor_map(args.sensor_map, list(STANDARD_SENSORS), "a standard placement"))
    names = take.names
    windows = _windows(args.second_pose)
    config = RecordingCalibrationConfig(max_std_g=args.max_std)
    # north auto on a file whose format says one north: take it, and say so (the override is --north own)
    north = "shared" if args.north == "auto" and take.one_north_source else args.north
    start = _take_start(args.pose, args.graph, north)
    try:
        record = calibrate_recording(take.acc_g, take.fps, take.labels, names,
                                     standard_segment_poses(names, tuple(windows), start.skeleton), config, windows,
                                     args.subject, path.stem, quat_wxyz=take.quat_wxyz, take_start=start)
    except ValueError as exc:
        raise CourtsideError(f"{path}: {exc}") from None
    if north != args.north:
        record.config["north_basis"] = take.one_north_source
    record.save(args.output)  # each file whole or not at all; a failure is one line naming it
    for sid, s in record.sensors.items():
        for reason in s.reasons:
            print(f"calibrate: warning: {sid} ({s.segment}): {reason}", file=sys.stderr)
    # the shanks whose heading came from walking: no orientations, or orientations that leave the twist a guess
    shanks = sorted({s.segment for s in record.sensors.values() if s.segment in SECOND_POSES["sit"]
                     and (s.orientation_yaw_rad is None or NO_TWIST_NOTE in s.reasons)})
    if shanks and "sit" not in windows:
        print(f"calibrate: note: {', '.join(shanks)}: heading from the walking swing plane, which follows the "
              "walker's toe-out (2-3 deg on normal gait, up to ~24 deg on unusual gaits); a long sit held in the "
              "take (--second-pose sit@START:END) measures it directly", file=sys.stderr)
    _say_north_basis(record.config)
    print(json.dumps({"output": args.output, "quality": record.quality_score, "grade": record.grade,
                      "passed": record.passed,
                      "sensors": {sid: {"segment": s.segment, "correction_deg": round(s.correction_deg, 1),
                                        "quality": round(s.quality, 2),
                                        **({} if s.orientation_yaw_rad is None else
                                           {"orientation_yaw_deg": round(float(np.degrees(s.orientation_yaw_rad)), 1)})}
                                  for sid, s in record.sensors.items()},
                      "pose": record.config.get("pose"), "north": record.config.get("north"),
                      "skeleton": record.skeleton}))
    return 0


def _say_north_basis(config: dict) -> None:
    """North auto: one line on stderr saying what was decided and why, and which flag overrides it. Why: neither
    test is sure on every take (docs/imu-import.md "One north": a short take of arm waving the database lacks can
    fail both), and the user often knows the answer: magnetometer-aided filters share one north."""
    basis = config.get("north_basis")
    if not basis:
        return
    if config.get("north") == "own":
        hint = ("magnetometer-aided (9-axis) sensors share one (Xsens MTw/DOT exports by default): if these are, "
                "pass --north shared")
    else:
        hint = "6-axis sensors (no magnetometer) each have their own: if these are, pass --north own"
    print(f"calibrate: note: north {config.get('north')} ({basis}); {hint}", file=sys.stderr)
