"""Camera command line: ``courtside camera {synth,calibrate,track} ...`` (or ``python -m gateway.camera.cli``).

* ``synth``: render a synthetic court clip (scripted rally or a shipped CMU clip) to a video file, with its
  court calibration (JSON, with intrinsics) and the per-frame ground truth (CSV).
* ``calibrate``: fit a court calibration from clicked keypoints (JSON ``{"keypoint name": [u, v], ...}``).
* ``track``: track the player in a video with a saved calibration; JSON lines of records on stdout (or
  ``--out``); with ``--truth`` prints the position RMS against it.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import cv2
import numpy as np

from gateway.camera.court import COURT_KEYPOINTS_M, keypoints_array
from gateway.camera.court_calibration import CourtCalibration
from engine.errors import ArgumentParser, MalformedFileError, report_errors
from engine.safe_load import read_json
from gateway.camera.errors import CameraError, CourtCalibrationFileError
from gateway.camera.paths import scripted_rally_path
from gateway.camera.sources import VideoFileSource
from gateway.camera.synthetic import SyntheticCourtCamera, default_court_camera
from gateway.camera.tracker import PlayerTracker, TrackerConfig

TRUTH_FIELDS = ("frame_index", "t_true_s", "x_m", "y_m", "heading_rad", "lift_m", "visible")


def synth(args: argparse.Namespace) -> int:
    camera = default_court_camera((args.width, args.height))
    body = None
    if args.clip:
        from engine.mocap import load_clip, sample_clips
        from gateway.camera.mocap_body import MocapBody

        body = MocapBody(load_clip(sample_clips()[args.clip], fps=args.fps), (args.x, args.y))
        path = body.path
    else:
        path = scripted_rally_path(args.seconds, seed=args.seed)
    names = list(COURT_KEYPOINTS_M)
    clicks = camera.project(np.column_stack([keypoints_array(names), np.zeros(len(names))]))
    CourtCalibration.fit(clicks, names=names, image_size=camera.image_size,
                         camera_matrix=camera.camera_matrix).save(args.calibration)
    writer = cv2.VideoWriter(str(args.out), cv2.VideoWriter_fourcc(*"mp4v"), args.fps, camera.image_size)
    if not writer.isOpened():
        raise CameraError(f"{args.out}: cannot open a video writer")
    with open(args.truth, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(TRUTH_FIELDS)
        opponents = [scripted_rally_path(path.duration_s, seed=args.seed + 1, side="far",
                                         start_s=float(path.t_s[0]))] if args.opponent else []
        for frame in SyntheticCourtCamera(path, camera=camera, fps=args.fps, body=body, seed=args.seed,
                                          opponents=opponents):
            writer.write(frame.image)
            tr = frame.truth
            out.writerow([frame.index, f"{tr.t_true_s:.6f}", f"{tr.x_m:.4f}", f"{tr.y_m:.4f}",
                          f"{tr.heading_rad:.4f}", f"{tr.lift_m:.4f}", int(tr.visible)])
    writer.release()
    print(f"wrote {args.out}, {args.calibration}, {args.truth}")
    return 0


def read_clicks(path: Path) -> tuple[list[str], np.ndarray]:
    """Clicked keypoints ``{"court keypoint name": [u, v], ...}`` -> (names, (N, 2) pixels); errors name the file."""
    try:
        clicks = read_json(path)  # depth-safe (issue 22)
    except MalformedFileError as exc:
        raise CourtCalibrationFileError(path, exc.problem) from None
    if not isinstance(clicks, dict):
        raise CourtCalibrationFileError(path, 'expected a JSON object {"keypoint name": [u, v], ...}')
    for name, uv in clicks.items():
        if name not in COURT_KEYPOINTS_M:
            raise CourtCalibrationFileError(path, f"unknown court keypoint {name!r}")
        if not (isinstance(uv, list) and len(uv) == 2 and all(isinstance(v, (int, float)) and np.isfinite(v)
                                                                for v in uv)):
            raise CourtCalibrationFileError(path, f"keypoint {name!r}: expected [u, v] pixel numbers, got {uv!r}")
    if len(clicks) < 4:
        raise CourtCalibrationFileError(path, f"a court calibration needs at least 4 keypoints, got {len(clicks)}")
    return list(clicks), np.array(list(clicks.values()), float)


def calibrate(args: argparse.Namespace) -> int:
    names, points = read_clicks(args.clicks)
    width, height = args.image_size
    k = None
    if args.focal_px:
        k = np.array([[args.focal_px, 0, (width - 1) / 2], [0, args.focal_px, (height - 1) / 2], [0, 0, 1]])
    try:
        calib = CourtCalibration.fit(points, names=names, image_size=(width, height), camera_matrix=k,
                                     ransac_threshold_px=args.ransac_px)
    except ValueError as exc:  # degenerate clicks (collinear, repeated...)
        raise CourtCalibrationFileError(args.clicks, f"cannot fit a calibration: {exc}") from None
    calib.save(args.out)
    print(json.dumps({"saved": str(args.out), **calib.summary()}))
    return 0


def track(args: argparse.Namespace) -> int:
    calib = CourtCalibration.load(args.calibration)
    tracker = PlayerTracker(calib, TrackerConfig(player_side=args.side))
    out = open(args.out, "w") if args.out else sys.stdout
    rows = []
    try:
        with VideoFileSource(args.video) as video:
            for frame in video:
                record = tracker.update(frame)
                if record is not None:
                    out.write(json.dumps({"frame_index": frame.index, **record.to_dict()}) + "\n")
                    rows.append((frame.index, record.x_m, record.y_m))
    finally:
        if out is not sys.stdout:
            out.close()
    if args.truth:
        with open(args.truth) as fh:
            truth = {int(r["frame_index"]): r for r in csv.DictReader(fh)}
        err = [np.hypot(x - float(truth[i]["x_m"]), y - float(truth[i]["y_m"]))
               for i, x, y in rows if i in truth and truth[i]["visible"] == "1"]
        print(f"tracked {len(err)} frames, position RMS {np.sqrt(np.mean(np.square(err))):.3f} m", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    return report_errors("courtside camera", _main, list(sys.argv[1:] if argv is None else argv))


def _main(argv: list[str]) -> int:
    parser = ArgumentParser(prog="courtside camera",
                            description="The overhead camera offline: render a synthetic court video with its "
                                        "calibration and ground truth (synth), fit a court calibration from clicked "
                                        "keypoints (calibrate), track the player in a video (track).",
                            epilog="`courtside camera COMMAND --help` for a command's options. Live, the gateway "
                                   "runs the camera (`courtside gateway --camera SRC --court court.json`).")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("synth", help="render a synthetic court clip + calibration + ground truth")
    p.add_argument("--out", type=Path, default=Path("court.mp4"), help="video file to write")
    p.add_argument("--calibration", type=Path, default=Path("court.json"),
                   help="court calibration of the rendered camera, for `courtside gateway --court`")
    p.add_argument("--truth", type=Path, default=Path("court_truth.csv"),
                   help="the player's true court position per frame (for `track --truth`)")
    p.add_argument("--seconds", type=float, default=10.0, help="length of the clip")
    p.add_argument("--clip", help="a shipped CMU clip name (e.g. 16_21) instead of the scripted rally")
    p.add_argument("--x", type=float, default=0.0, help="court x (m) of the clip's mean root position")
    p.add_argument("--y", type=float, default=-8.0, help="court y (m) of the clip's mean root position")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate of the video")
    p.add_argument("--width", type=int, default=800, help="frame width, pixels")
    p.add_argument("--height", type=int, default=450, help="frame height, pixels")
    p.add_argument("--seed", type=int, default=0, help="random seed of the scripted rally and the image noise")
    p.add_argument("--opponent", action="store_true", help="an opponent rallies on the far half (a distractor)")
    p.set_defaults(run=synth)
    p = sub.add_parser("calibrate", help="fit a court calibration from clicked keypoints")
    p.add_argument("--clicks", required=True, help='JSON {"near_baseline_left_doubles": [u, v], ...}')
    p.add_argument("--image-size", type=int, nargs=2, required=True, metavar=("W", "H"),
                   help="size of the image the keypoints were clicked on, pixels")
    p.add_argument("--focal-px", type=float, help="focal length (px) if known: enables the camera pose")
    p.add_argument("--ransac-px", type=float, help="RANSAC inlier threshold (px) to survive a misclick")
    p.add_argument("--out", type=Path, default=Path("court.json"), help="court calibration file to write")
    p.set_defaults(run=calibrate)
    p = sub.add_parser("track", help="track the player in a video file")
    p.add_argument("--video", type=Path, required=True, help="video file of the overhead camera")
    p.add_argument("--calibration", type=Path, required=True,
                   help="court calibration of that camera (from `calibrate` or `synth`)")
    p.add_argument("--out", type=Path, help="JSON-lines output (default stdout)")
    p.add_argument("--truth", type=Path, help="ground-truth CSV from `synth`: print the position RMS")
    p.add_argument("--side", choices=("near", "far"), help="half the instrumented player starts on (acquire "
                   "there, then follow him; default: the largest moving blob anywhere)")
    p.set_defaults(run=track)
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except OSError as exc:  # an output that cannot be written (the inputs raise CameraError themselves)
        raise CameraError(f"{exc.filename or ''}: {exc.strerror or exc}") from None


if __name__ == "__main__":
    raise SystemExit(main())
