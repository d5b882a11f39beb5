"""The path a user takes with a real recording (issue 29), on a simulated one: a CSV of six IMUs (specific force in
m/s² in each sensor's frame, the vendor's orientation quaternion in its own earth frame, 60 Hz) strapped any way
(uniform over all rotations), starting in an A-pose, of motions held out of the graph ->
`courtside import-imu` -> `courtside calibrate --graph` -> `courtside synthesize --calibration`, scored against the
mocap truth for the written BVH (read back) and the saved poses, and the console's live path (the graph file's
engine with that record, `load_spec`, pushed frame by frame) -- beside the same take with a perfect calibration
(the simulated yaws and straps), with the hold read perfectly (`hold_floor_record`: the best any held-pose
calibration can do, so perfect minus it is what the hold itself cannot show), with orientations but no
calibration, accelerations only, and the mean pose at the camera's root, a camera-only search and the database
oracle, all in one run.

    nice .venv/bin/python bench/bench_real_recording.py --mocap-dir ../shared/mocap --graph b1.npz \\
        [--groups respond,call] [--start-pose apose:70] [--strapping random|nominal] [--filter 6axis|9axis]
        [--seconds 50] [--posing-error-deg 3] [--forearm-roll-deg 0] [--north auto|shared|own] [--seed 0]
        [--tilt-noise-deg D] [--north-spread-deg D] [--seeds N]

``--graph``: a graph built from ``--pattern`` over ``--mocap-dir`` (`courtside build-graph --mocap-dir ...
--pattern ... --msv -o b1.npz`); every clip of the held-out groups is removed from it for the run.

The simulation: the take's clips chained (engine.evaluation.takes), the athlete first holding the start pose for
1.5 s (each segment `--posing-error-deg` (3) off the template, the arms at the stated angle, both forearms rolled
`--forearm-roll-deg` about their bones: positive turns the palms backwards from facing the body), the standard
sensors' true orientations and accelerations (the measured real-sensor error model) at 60 Hz, each sensor strapped
by its own rotation, its orientation read through a magnetometer-free filter's errors (``--filter 6axis``: random
yaw per sensor, drift, 2 deg of wandering tilt: `OrientationErrorModel.realistic` without its own strapping) or a
magnetometer-aided one's (``9axis``, as Xsens MTw/DOT export: one north, each sensor 4 deg off it:
`OrientationErrorModel.magnetometer`). The perfect record holds each sensor's yaw at the take's start and its strap.

One recording is one draw of straps, posing and filter errors, and the gap to the perfect calibration moves by
tenths of a centimetre from draw to draw on one take: ``--seeds N`` draws N recordings of the same take (seeds
``--seed`` on), prints each one's table, their mean, and each one's gap (from the take minus perfect, and the
held pose's floor minus perfect).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from engine.evaluation import baselines, engines, simulate
from engine.evaluation.labels import clip_label
from engine.evaluation.metrics import frame_errors
from engine.evaluation.takes import Take, chain_clips
from engine.graph.graph import MotionGraph
from engine.graph.online_engine import load_spec
from engine.graph.root_fusion import RootFusion
from engine.graph.viterbi import SearchWeights
from engine.graph.warp import RootWarp
from engine.mocap import (SEED000_SENSORS, SensorErrorModel, forward_kinematics, load_clip, load_sensor_calibration,
                          read_bvh, standard_placements, virtual_orientations)
from engine.mocap import quaternions as quat
from engine.mocap.calibrated import SKELETON, orientation_fields, skeleton_identity, strap_field
from engine.mocap.orientation import OrientationErrorModel, from_device_earth, random_rotations, yaw_about_up
from engine.mocap.orientation_calibration import mean_orientation, pose_sensor_orientations
from engine.stream.offline import synthesize_take
from engine.stream.poses_file import load_poses
from gateway.cli import main as courtside

RATE_HZ = 60.0
HOLD_S = 1.5
GRAVITY_MPS2 = 9.80665
NAMES = list(SEED000_SENSORS)
# the rows each draw's gaps are read from
FROM_TAKE = "calibrate --graph (start pose found)"
FLOOR = "the hold read perfectly (the held pose's floor)"
PERFECT = "perfect calibration"


@dataclass
class Recording:
    """The simulated recording: readings at `RATE_HZ` from the hold's start, the truth after it."""

    take: Take
    acc_mps2: np.ndarray      # (F, S, 3) specific force in each sensor's frame
    quat_device: np.ndarray   # (F, S, 4) sensor -> device earth (Z up), w first
    yaw_rad: np.ndarray       # (S,) each sensor's earth-frame yaw at the take's start (the perfect calibration)
    strap_wxyz: np.ndarray    # (S, 4) each sensor's strapping (sensor axes -> nominal sensor frame)


def parse_start_pose(text: str) -> tuple[str, float | None]:
    name, _, angle = text.partition(":")
    return name, (float(angle) if angle else (70.0 if name == "apose" else None))


FILTERS = {"6axis": OrientationErrorModel.realistic, "9axis": OrientationErrorModel.magnetometer}


def forearm_roll(forearm_roll_deg: float) -> np.ndarray:
    """(S, 4) each sensor's turn in its nominal frame while the athlete holds the pose with both forearms rolled
    `forearm_roll_deg` about the bone (X of a limb sensor's nominal frame; mirrored on the right arm, so positive
    turns both palms backwards): the template's palms face the body, and a real athlete's need not."""
    sign = np.array([{"left_forearm": 1.0, "right_forearm": -1.0}.get(name, 0.0) for name in NAMES])
    return quat.from_rotvec(np.outer(sign * np.radians(forearm_roll_deg), [1.0, 0.0, 0.0]))


def simulate_recording(take: Take, start_pose: str, strapping: str, orientation_filter: str,
                       rng: np.random.Generator, posing_error_deg: float = 3.0, forearm_roll_deg: float = 0.0,
                       filter_changes: dict[str, float] | None = None) -> Recording:
    """Module doc: the hold, then the take; strapped, filtered (`filter_changes`: OrientationErrorModel fields
    set otherwise than the filter's, e.g. ``tilt_noise_deg``, to see what each error costs)."""
    pose, arm_deg = parse_start_pose(start_pose)
    skeleton = take.segments[0].motion.skeleton
    acc_g, _ = simulate.accelerometers(take, NAMES, SensorErrorModel.measured_real(), rng, fps=RATE_HZ)
    q_true, _ = simulate.per_segment(take, RATE_HZ, lambda m: virtual_orientations(m, standard_placements(
        m.skeleton, NAMES)))
    n_hold = int(round(HOLD_S * RATE_HZ))
    held = quat.multiply(pose_sensor_orientations(skeleton, NAMES, pose, float(take.heading_rad[0]), arm_deg),
                         forearm_roll(forearm_roll_deg))
    held = quat.multiply(random_rotations(rng, len(NAMES), np.radians(posing_error_deg)), held)
    held_acc = quat.rotate(quat.conjugate(held), np.array([0.0, 1.0, 0.0]))  # still: 1 g up, in the sensor frame
    held_acc = held_acc[None] + rng.normal(0.0, 0.01, (n_hold, len(NAMES), 3))
    q_nominal = np.concatenate([np.repeat(held[None], n_hold, axis=0), q_true])
    acc_nominal = np.concatenate([held_acc, acc_g[:len(q_true)]])
    strap = quat.from_matrix(Rotation.random(len(NAMES), random_state=rng.integers(1 << 31)).as_matrix()) \
        if strapping == "random" else np.tile(quat.identity(), (len(NAMES), 1))
    q_sensor = quat.multiply(q_nominal, strap)                 # the strapped sensor's orientation in the world
    acc_sensor = quat.rotate(quat.conjugate(strap), acc_nominal)  # its readings in its own axes
    model = replace(FILTERS[orientation_filter](), misalignment_deg=0.0, **(filter_changes or {}))
    errors = model.draw(len(q_sensor), len(NAMES), RATE_HZ, rng)
    return Recording(take, acc_sensor * GRAVITY_MPS2, errors.apply(q_sensor), errors.yaw_rad[n_hold], strap)


def held_out_take(mocap_dir: Path, pattern: str, graph: MotionGraph, graph_name: str, groups: list[str],
                  seconds: float) -> tuple[Take, MotionGraph, list[str]]:
    """The groups' clips chained into one take of at least `seconds` (all of them if shorter), the graph without
    any clip of those groups, and the chained clips' contents. Exits naming the graph if it was not built from
    `pattern` over `mocap_dir`."""
    paths = sorted(mocap_dir.glob(pattern))
    if graph.clip_names != [path.stem for path in paths]:
        sys.exit(f"{graph_name}: not built from {pattern} ({len(graph.clip_names)} vs {len(paths)} clips)")
    labels = [clip_label(path).content for path in paths]
    held = [i for i, label in enumerate(labels) if label in groups]
    motions = {i: load_clip(paths[i], fps=graph.config.fps) for i in held}
    chosen, total = [], 0.0
    for i in held:
        if total < seconds:
            chosen.append(i)
            total += motions[i].duration_s
    take = chain_clips([motions.get(i) for i in range(len(paths))], chosen, labels)
    return take, graph.without_clips(held), [labels[i] for i in chosen]


def write_csv(path: Path, rec: Recording) -> list[str]:
    """The recording as a vendor-style CSV; returns the import-imu arguments that read it."""
    n = len(rec.acc_mps2)
    columns, header, args = [np.arange(n) / RATE_HZ], ["time_s"], ["--time", "time_s", "--time-unit", "s"]
    for k, name in enumerate(NAMES):
        acc = [f"{name}_a{a}" for a in "xyz"]
        qs = [f"{name}_q{a}" for a in "wxyz"]
        header += acc + qs
        columns += [rec.acc_mps2[:, k, i] for i in range(3)] + [rec.quat_device[:, k, i] for i in range(4)]
        args += ["--sensor", f"{name}={','.join(acc)}", "--quat", f"{name}={','.join(qs)}"]
    np.savetxt(path, np.column_stack(columns), delimiter=",", header=",".join(header), comments="", fmt="%.7g")
    return args


def write_record(path: Path, skeleton, yaw_rad: np.ndarray, mount_wxyz: np.ndarray) -> None:
    """A calibration record of each sensor's earth yaw and strapping (sensor axes -> nominal sensor frame), with
    its mounting (the nominal placement turned by the strap) for the accelerations."""
    placements = standard_placements(skeleton, NAMES)
    sensors = {}
    for k, p in enumerate(placements):
        angle = float(np.degrees(np.linalg.norm(quat.to_rotvec(mount_wxyz[k]))))
        sensors[f"{p.name}"] = {"segment": p.name, "rotation": (p.rotation @ quat.to_matrix(mount_wxyz[k])).tolist(),
                                "gravity_sensor_g": [0, 1, 0], "norm_error_g": 0.0, "correction_deg": angle,
                                "passed": True, **orientation_fields(yaw_rad[k], mount_wxyz[k]),
                                **strap_field(mount_wxyz[k])}
    path.write_text(json.dumps({"schema": "courtside.sensor_calibration", "schema_version": 1, "sensors": sensors,
                                SKELETON: skeleton_identity(skeleton, "the graph's skeleton")}))


def perfect_record(path: Path, rec: Recording, skeleton) -> None:
    """The record a perfect calibration would write: each sensor's true yaw and strap."""
    write_record(path, skeleton, rec.yaw_rad, rec.strap_wxyz)


def hold_floor_record(path: Path, rec: Recording, skeleton, start_pose: str, orientation_filter: str) -> None:
    """The best record any held-pose calibration can write: the hold read with the true heading and arm angle
    (and each sensor's own north on 6-axis filters, the sensors' mean north on 9-axis ones: what a hold cannot
    split from the strap's twist, given), so the strap M = P⁻¹ yaw(-δ) Q_held still carries what the hold itself
    gets wrong -- the athlete's posing error, the filter's tilt wander during the hold, and (9-axis) each
    sensor's offset from the one north. Its distance to the perfect record is the floor of the hold; calibrate's
    distance to it, what the solve loses."""
    pose, arm_deg = parse_start_pose(start_pose)
    n_hold = int(round(HOLD_S * RATE_HZ))
    held = from_device_earth(mean_orientation(rec.quat_device[:n_hold]))
    template = pose_sensor_orientations(skeleton, NAMES, pose, float(rec.take.heading_rad[0]), arm_deg)
    yaw = rec.yaw_rad if orientation_filter == "6axis" else \
        np.full(len(NAMES), float(np.angle(np.mean(np.exp(1j * rec.yaw_rad)))))
    mount = quat.multiply(quat.conjugate(template), quat.multiply(yaw_about_up(-yaw), held))
    write_record(path, skeleton, yaw, quat.canonical_sign(mount))


def run(argv: list[str]) -> str:
    """One courtside command in this process; its stdout (exit code 0 asserted)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = courtside(argv)
    if code != 0:
        raise SystemExit(f"courtside {' '.join(argv)} exited {code}")
    return out.getvalue()


def score(joints_m: np.ndarray, t_s: np.ndarray, take: Take) -> float:
    """Root-relative error (cm) of world joints at times t_s (from the recording's start) on the take's truth."""
    frames = np.round((np.asarray(t_s) - HOLD_S) * take.fps).astype(int)
    keep = (frames >= 0) & (frames < take.n_frames)
    pred = np.full_like(take.joints_m, np.nan)
    pred[frames[keep]] = joints_m[keep]
    ok = np.isfinite(pred).all(axis=(1, 2))
    errors = frame_errors(pred[ok], take.joints_m[ok], take.skeleton)
    return float(np.mean(errors.root_relative_cm))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--mocap-dir", required=True)
    p.add_argument("--pattern", default="bandai-namco-1/data/*.bvh")
    p.add_argument("--graph", required=True, help="graph of every clip the pattern matches")
    p.add_argument("--groups", default="respond,call", help="contents held out and acted in the take")
    p.add_argument("--seconds", type=float, default=50.0, help="take length (its groups' clips chained)")
    p.add_argument("--start-pose", default="apose:70", help="npose, tpose or apose:DEG (arms DEG out from down)")
    p.add_argument("--strapping", choices=("random", "nominal"), default="random")
    p.add_argument("--filter", choices=tuple(FILTERS), default="6axis",
                   help="the IMUs' orientation filter: 6axis (a north per sensor, drifting) or 9axis (one north)")
    p.add_argument("--posing-error-deg", type=float, default=3.0,
                   help="sd of each segment's turn off the start pose's template (degrees)")
    p.add_argument("--forearm-roll-deg", type=float, default=0.0,
                   help="both forearms rolled about the bone in the held pose (degrees; positive: palms backwards)")
    p.add_argument("--tilt-noise-deg", type=float, help="the filter's wandering tilt error (sd, degrees; default: "
                   "the filter's, 2 on 6axis, 1 on 9axis)")
    p.add_argument("--north-spread-deg", type=float, help="9axis: each sensor's offset from the one north (sd, "
                   "degrees; default 4)")
    p.add_argument("--north", choices=("auto", "shared", "own"), default="auto",
                   help="calibrate --north (default auto, as a user who does not say)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--seeds", type=int, default=1, help="recordings drawn (seeds --seed on): each one's table, "
                   "then their mean and each one's gap to the perfect calibration")
    args = p.parse_args()
    if args.north_spread_deg is not None and args.filter != "9axis":
        p.error("--north-spread-deg is the 9axis filter's (a 6axis filter has a north per sensor)")
    graph = MotionGraph.load(args.graph)
    take, train, chosen_labels = held_out_take(Path(args.mocap_dir), args.pattern, graph, args.graph,
                                               args.groups.split(","), args.seconds)
    changes = {name: value for name, value in (("tilt_noise_deg", args.tilt_noise_deg),
                                               ("north_spread_deg", args.north_spread_deg)) if value is not None}
    print(f"take: {take.n_frames / take.fps:.1f} s of {', '.join(sorted(set(chosen_labels)))} "
          f"({len(chosen_labels)} clips held out with their groups), start pose {args.start_pose} held {HOLD_S} s "
          f"({args.posing_error_deg:g} deg posing error, forearms rolled {args.forearm_roll_deg:g} deg), "
          f"strapping {args.strapping}, {args.filter} filter, {RATE_HZ:g} Hz CSV in m/s2")
    by_seed = {}
    for seed in range(args.seed, args.seed + args.seeds):
        by_seed[seed], found = measure(args, take, train, seed, changes)
        print(f"\nseed {seed}: calibrate --graph found pose {found['pose']}, north {found['north']}")
        print_table(by_seed[seed])
    if args.seeds > 1:
        print(f"\nmean over seeds {args.seed}-{args.seed + args.seeds - 1}")
        print_table({name: {key: float(np.mean([rows[name][key] for rows in by_seed.values()]))
                            for key in cells} for name, cells in by_seed[args.seed].items()})
    gaps = [rows[FROM_TAKE]["poses"] - rows[PERFECT]["poses"] for rows in by_seed.values()]
    floors = [rows[FLOOR]["poses"] - rows[PERFECT]["poses"] for rows in by_seed.values()]
    print(f"\nfrom the take minus perfect, per seed: {' '.join(f'{g:+.2f}' for g in gaps)} (mean {np.mean(gaps):+.2f}, "
          f"{sum(g <= 0.3 for g in gaps)} of {len(gaps)} within 0.3); the hold's floor minus perfect: "
          f"{' '.join(f'{g:+.2f}' for g in floors)} (mean {np.mean(floors):+.2f})")


def measure(args: argparse.Namespace, take: Take, train: MotionGraph, seed: int, changes: dict[str, float]
            ) -> tuple[dict[str, dict[str, float]], dict]:
    """One simulated recording (seed `seed`) through every case and baseline: {row: {"poses", "bvh",
    "console": cm}} and what calibrate found."""
    rng = np.random.default_rng(seed)
    rec = simulate_recording(take, args.start_pose, args.strapping, args.filter, rng, args.posing_error_deg,
                             args.forearm_roll_deg, changes)
    rows: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory(prefix="courtside-real-") as folder:
        work = Path(folder)
        train.save(work / "graph.npz")
        csv_args = write_csv(work / "take.csv", rec)
        run(["import-imu", str(work / "take.csv"), "--format", "csv", *csv_args, "-o", str(work / "take.npz"),
             "--quiet"])
        acc_args = [a for a in csv_args if not a.startswith("--quat") and "_q" not in a]
        run(["import-imu", str(work / "take.csv"), "--format", "csv", *acc_args, "-o", str(work / "acc.npz"),
             "--quiet"])
        found = json.loads(run(["calibrate", str(work / "take.npz"), "--graph", str(work / "graph.npz"), "--north",
                                args.north, "-o", str(work / "from_take.json")]))
        run(["calibrate", str(work / "take.npz"), "--graph", str(work / "graph.npz"), "--pose", "none", "--north",
             args.north, "-o", str(work / "from_motion.json")])
        perfect_record(work / "perfect.json", rec, train.skeleton)
        hold_floor_record(work / "hold_floor.json", rec, train.skeleton, args.start_pose, args.filter)
        cases = {"accelerations only": ("acc.npz", None), "orientations, no calibration (tilt)": ("take.npz", None),
                 FROM_TAKE: ("take.npz", "from_take.json"),
                 "calibrate --graph --pose none (from motion)": ("take.npz", "from_motion.json"),
                 FLOOR: ("take.npz", "hold_floor.json"), PERFECT: ("take.npz", "perfect.json")}
        for name, (take_file, record) in cases.items():
            extra = [] if record is None else ["--calibration", str(work / record)]
            run(["synthesize", "--graph", str(work / "graph.npz"), "--input", str(work / take_file), "-o",
                 str(work / "out.bvh"), "--save-poses", str(work / "poses.npz"), "--quiet", *extra])
            poses = load_poses(work / "poses.npz")
            bvh = forward_kinematics(read_bvh(work / "out.bvh", scale="cm"))[0]
            calibration = None if record is None else load_sensor_calibration(work / record)
            live = synthesize_take(load_spec(work / "graph.npz", calibration), work / take_file, 0.5)
            rows[name] = {"poses": score(poses.joint_positions_m, poses.t_s, take),
                          "bvh": score(bvh, poses.t_s, take),
                          "console": score(np.stack([q.joint_positions_m for q in live]),
                                           np.array([q.t_s for q in live]), take)}
    cam = simulate.camera_track(take, simulate.CameraModel(), np.random.default_rng(seed + 1))
    cam_pos, cam_head = cam.filled()
    t_truth = HOLD_S + np.arange(take.n_frames) / take.fps
    camera_only = engines.motion_graph(train, None, (), cam.position_m, cam.heading_rad,
                                       replace(SearchWeights.camera_following(), acc=0.0), True, RootWarp(),
                                       None, RootFusion())
    oracle, _ = baselines.database_oracle(train, take.joints_m, take.skeleton, cam_pos, cam_head)
    for name, joints in (("mean pose at the camera's root", baselines.mean_pose(train, cam_pos, cam_head)),
                         ("camera-only search", camera_only.joints_m), ("database oracle", oracle)):
        rows[name] = {"poses": score(joints, t_truth, take)}
    return rows, found


def print_table(rows: dict[str, dict[str, float]]) -> None:
    print(f"{'root-relative error, cm':48s} {'saved poses':>12s} {'BVH file':>9s} {'console':>8s}")
    for name, r in rows.items():
        cells = [f"{r[k]:.2f}" if k in r else "-" for k in ("poses", "bvh", "console")]
        print(f"{name:48s} {cells[0]:>12s} {cells[1]:>9s} {cells[2]:>8s}")


if __name__ == "__main__":
    main()
