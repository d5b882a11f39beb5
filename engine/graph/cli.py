"""`courtside build-graph | synthesize | evaluate` (entry points declared in pyproject.toml)."""
from __future__ import annotations

import argparse
import glob
import json
import re
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from engine.atomic_write import refuse_overwriting_inputs
from engine.errors import ArgumentParser, CourtsideError, MalformedFileError, check_output_dir, cli_command
from engine.progress import add_quiet_argument
from engine.mocap.orientation_calibration import OrientationCalibration
from engine.mocap import (SEED000_SENSORS, STANDARD_SENSORS, load_database, load_sensor_calibration,
                          placements_from_calibration, sample_clips, standard_placements, write_bvh)

from .config import GraphConfig
from .graph import MotionGraph, build_from_clips
from .input_checks import check_database, check_lag, check_non_negative, check_path_length, parse_sensor_map
from .mocap_adapter import clips_from_motions, mocap_sensor_model
from .orientation_term import places_sensors
from .report import coverage_warning, format_report, graph_report, motion_range
from .root_fusion import RootFusion
from .viterbi import SearchWeights, default_weights
from .warp import RootWarp

_BANDAI = re.compile(r"dataset-\d+_(?P<content>[a-z-]+)_(?P<style>[a-z-]+)_\d+")


def clip_label(path: Path) -> str:
    """Action label of a clip for human constraints: the Bandai content name, else the file stem."""
    m = _BANDAI.match(path.stem)
    return m.group("content") if m else path.stem


def database_paths(args: argparse.Namespace) -> list[Path]:
    """Clip files from positional paths, --sample (shipped CMU subject 16) or --mocap-dir + --pattern."""
    paths = [Path(p) for p in getattr(args, "clips", []) or []]
    if args.sample:
        paths += [p for name, p in sample_clips().items() if name.startswith("16_")]
    if args.mocap_dir:
        paths += [Path(p) for p in sorted(glob.glob(str(Path(args.mocap_dir) / args.pattern)))]
    if args.max_clips:
        paths = paths[: args.max_clips]
    if not paths:
        raise CourtsideError("no clips: give clip files, --sample, or --mocap-dir with --pattern (matching files)")
    return paths


def _add_database_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--sample", action="store_true", help="use the CMU subject-16 clips shipped in engine/data")
    p.add_argument("--mocap-dir", help="a mocap folder, e.g. ../shared/mocap")
    p.add_argument("--pattern", default="bandai-namco-1/data/*.bvh", help="glob under --mocap-dir")
    p.add_argument("--max-clips", type=int, default=0, help="use only the first N clips (0 = all)")
    p.add_argument("--sensors", nargs="+", default=list(SEED000_SENSORS), choices=STANDARD_SENSORS,
                   help="worn sensor placements (seed 000: forearms, shins, lower back, chest)")
    p.add_argument("--threshold", type=float, default=GraphConfig.transition_threshold_m,
                   help="transition threshold, RMS point-cloud distance in metres")


def load_clips(args: argparse.Namespace, config: GraphConfig):
    paths = database_paths(args)
    motions = load_database(paths, fps=config.fps)
    check_database(paths, motions, config.fps)
    placements = standard_placements(motions[0].skeleton, args.sensors)
    if getattr(args, "calibration", None):
        # measured sensor-to-segment rotations instead of the nominal mounting (ValueError: other joint frames)
        calibration = load_sensor_calibration(args.calibration)
        placements = placements_from_calibration(placements, calibration)
        args.calibrated_sensors = sorted(set(calibration.rotations) & set(args.sensors))
        if calibration.failed:
            print(f"warning: {args.calibration}: sensors on {', '.join(calibration.failed)} did not pass the "
                  "calibration checks (their rotations are used anyway)", file=sys.stderr)
    config.sensor_names = list(args.sensors)
    clips = clips_from_motions(motions, placements, config, [clip_label(p) for p in paths])
    return motions, clips, mocap_sensor_model(motions[0].skeleton, placements, config.fps)


@cli_command("courtside build-graph")
def build_graph_main(argv: list[str]) -> int:
    p = ArgumentParser(prog="courtside build-graph", description="Build a motion graph from mocap clips.")
    p.add_argument("clips", nargs="*", help=".bvh or .amc files (one skeleton)")
    _add_database_args(p)
    p.add_argument("-o", "--output", required=True, help="graph .npz (a .json summary is written beside it)")
    p.add_argument("--msv", action="store_true", help="add motion speed variations")
    p.add_argument("--interp", action="store_true", help="add interpolated motions")
    p.add_argument("--no-connect", action="store_true",
                   help="keep the graph as built: no relaxed transitions for poorly connected clips and no pruning "
                        "to the largest strongly connected component (default: connect and prune)")
    p.add_argument("--calibration", metavar="RECORD",
                   help="sensor-calibration record (.calibration.json from the gateway's calibration workflow): "
                        "virtual sensors use its measured sensor-to-segment rotations")
    add_quiet_argument(p)
    args = p.parse_args(argv)
    refuse_overwriting_inputs([args.output, Path(args.output).with_suffix(".json")],
                              database_paths(args), "the graph or its report")
    check_non_negative("--threshold", [args.threshold], positive=True)
    config = GraphConfig(msv=args.msv, interp=args.interp, transition_threshold_m=args.threshold,
                         connect=not args.no_connect)
    check_output_dir(args.output)
    t0 = time.perf_counter()
    motions, clips, sensor_model = load_clips(args, config)
    t1 = time.perf_counter()
    graph = build_from_clips(clips, config, sensor_model)
    graph.skeleton = motions[0].skeleton
    t2 = time.perf_counter()
    graph.save(args.output)
    summary = {**graph.summary(), "config": json.loads(config.to_json()), "load_s": round(t1 - t0, 2),
               "build_s": round(t2 - t1, 2), "frames": int(sum(c.n_frames for c in clips))}
    if args.calibration:
        summary["calibration"] = {"record": str(args.calibration), "sensors": args.calibrated_sensors}
    from .budget import live_verdict, online_rate
    from .viterbi import PathsExhaustedError

    try:
        cpu_rate, wall_rate = online_rate(graph)
    except PathsExhaustedError as exc:  # a --no-connect graph: the timing run outlasts its paths; the graph is saved
        print(f"note: online speed not measured: {exc}", file=sys.stderr)
    else:
        summary["online_samples_per_cpu_s"] = round(cpu_rate, 1)
        summary["online_samples_per_s"] = round(wall_rate, 1)
        verdict = live_verdict(graph, cpu_rate, wall_rate)
        if verdict:
            print(verdict, file=sys.stderr)
    if graph.build_report and "interpolation" in graph.build_report:
        i = graph.build_report["interpolation"]
        print(f"interpolation: {i['alignments_found']} alignments ({i['frames_found']} frames) found, the cleanest "
              f"{i['alignments_kept']} ({i['frames_kept']} frames) kept under the cap of {i['cap_frames']} frames",
              file=sys.stderr)
    if graph.build_report:
        summary.update(graph.build_report)
    if graph.build_report and "component" in graph.build_report:
        c = graph.build_report["component"]
        print(f"component step: largest strongly connected component held {100 * c['share_before']:.1f} % of "
              f"{c['frames']} frames; {c['relaxed_transitions']} relaxed transitions (thresholds "
              f"{c['thresholds_used_m']} m) -> {100 * c['share_connected']:.1f} %; pruned {c['pruned_nodes']} nodes "
              f"({c['pruned_frames']} database frames), {c['pruned_edges']} edges; {c['clips_kept']} of "
              f"{c['clips_total']} clips kept", file=sys.stderr)
    Path(args.output).with_suffix(".json").write_text(json.dumps(summary, indent=2))
    print(format_report(graph_report(graph)))
    print(json.dumps(summary))  # last line: the machine-readable summary scripts parse
    return 0


def graph_info_main(argv: list[str]) -> int:
    p = ArgumentParser(prog="courtside graph-info",
                       description="What a motion graph can do: size, strongly connected components, "
                                            "dead ends, clips reachable, turn rates and speeds covered.")
    p.add_argument("graph", help="graph .npz from build-graph")
    print(format_report(graph_report(MotionGraph.load(p.parse_args(argv).graph))))
    return 0


def add_search_args(p: argparse.ArgumentParser) -> None:
    """--weights and --forgetting, shared by `synthesize` and `evaluate` (read back by `weights_from_args`)."""
    p.add_argument("--weights", nargs=3, type=float, default=None, metavar=("W_A", "W_P", "W_O"),
                   help="search weights (default: 1 1 0.3 with root warping, the paper's 0.5 1 1 without)")
    p.add_argument("--forgetting", type=float, default=None, metavar="LAMBDA",
                   help="per-sample fading of every path's accumulated cost, in (0, 1]; 1 = seed 000's Viterbi, "
                        "one path, unblended (default: 0.9 with root warping, deciding each sample 0.2 s later and "
                        "blending the 8 best paths; 1 without; engine/graph/viterbi.SearchWeights)")
    p.add_argument("--orientation-weight", type=float, default=None, metavar="W",
                   help="weight of the orientation term (takes with quat_wxyz; engine/graph/orientation_term.py) "
                        "relative to the accelerations' (default 1 with root warping, 0 = orientations ignored)")
    p.add_argument("--orientation-heading", type=float, default=None, metavar="SHARE",
                   help="share of the orientation term's heading part (limb heading relative to the pelvis sensor, "
                        "per-sensor yaw offsets learnt online) against its tilt part (default 0: tilt alone)")
    p.add_argument("--segment-pose", type=float, default=None, metavar="GAIN",
                   help="takes with quat_wxyz: how far each worn segment is turned from the played database pose "
                        "onto its measured orientation (engine/graph/orientation_pose.py; default 1 = all the way, "
                        "0 = play database poses as they are)")
    p.add_argument("--hinge-share", type=float, default=None, metavar="SHARE",
                   help="takes with quat_wxyz: share of a worn forearm's / shin's turn that the unworn upper arm / "
                        "thigh takes about the shoulder / hip, keeping the played elbow / knee angle "
                        "(engine/graph/orientation_pose.py; 0 = only the worn segment turns)")
    p.add_argument("--forearm-roll", type=float, default=None, metavar="SHARE",
                   help="takes with quat_wxyz and an orientation calibration: weight of a worn forearm's roll about "
                        "its bone in the search's orientation term, against where the bone points "
                        "(engine/graph/orientation_term.py; default 0: the bone alone, 1 = as much)")
    p.add_argument("--limb-prior", type=int, default=None, metavar="K",
                   help="when posing: the unworn upper arm / thigh points where the K database poses nearest in "
                        "the worn forearm's / shin's orientation relative to the chest / pelvis (tilts alone without "
                        "a calibration) have it, as the played forearm / shin misfits (engine/graph/limb_prior.py; "
                        "default 64, 0 = the hinge share instead)")
    p.add_argument("--strap-refine", type=float, default=None, metavar="SECONDS",
                   help="takes with quat_wxyz and an orientation calibration: time constant of the running estimate "
                        "of each sensor's strapping error from the played poses (default 20; 0 = trust the N-pose "
                        "capture as it is)")
    p.add_argument("--gravity-weight", type=float, default=None, metavar="W",
                   help="accelerations only: weight of the tilt from low-passed accelerations "
                        "(engine/graph/gravity_term.py) relative to the accelerations' (default 0 = off)")
    p.add_argument("--sensor-weighting", type=float, default=None, metavar="POWER",
                   help="weight each sensor's accelerations by (between-pose / within-pose spread) ** POWER over "
                        "the database (engine/graph/sensor_weights.py; default 0 = every sensor alike; negative "
                        "powers favour the sensors whose accelerations vary less between poses)")


def weights_from_args(args: argparse.Namespace, warp: RootWarp) -> SearchWeights:
    """The preset that goes with `warp` (warp.default_weights), with --weights / --forgetting replacing its
    values; a bad value is one line, no traceback."""
    weights = default_weights(warp)
    if args.weights:
        check_non_negative("--weights", args.weights)
        weights = replace(weights, acc=args.weights[0], position=args.weights[1], heading=args.weights[2])
    if args.forgetting is not None:
        if not (np.isfinite(args.forgetting) and 0 < args.forgetting <= 1):
            raise CourtsideError(f"--forgetting {args.forgetting!r}: must be in (0, 1]")
        # the blend of the best paths needs per-sample decisions: forgetting 1 is seed 000's search, unblended
        weights = replace(weights, forgetting=args.forgetting,
                          blend_paths=weights.blend_paths if args.forgetting < 1 else 1)
    if args.orientation_weight is not None:
        check_non_negative("--orientation-weight", [args.orientation_weight])
        weights = replace(weights, orientation=args.orientation_weight)
    if args.orientation_heading is not None:
        check_non_negative("--orientation-heading", [args.orientation_heading])
        weights = replace(weights, orientation_heading=args.orientation_heading)
    for option, attr in (("--segment-pose", "segment_pose"), ("--hinge-share", "hinge_share"),
                         ("--forearm-roll", "forearm_roll")):
        value = getattr(args, attr)
        if value is not None:
            if not (np.isfinite(value) and 0 <= value <= 1):
                raise CourtsideError(f"{option} {value!r}: must be in [0, 1]")
            weights = replace(weights, **{attr: value})
    if args.limb_prior is not None:
        check_non_negative("--limb-prior", [args.limb_prior])
        weights = replace(weights, limb_prior_k=args.limb_prior)
    if args.strap_refine is not None:
        check_non_negative("--strap-refine", [args.strap_refine])
        weights = replace(weights, strap_refine_s=args.strap_refine)
    if args.gravity_weight is not None:
        check_non_negative("--gravity-weight", [args.gravity_weight])
        weights = replace(weights, gravity=args.gravity_weight)
    if args.sensor_weighting is not None:
        if not np.isfinite(args.sensor_weighting):
            raise CourtsideError(f"--sensor-weighting {args.sensor_weighting!r}: must be a finite number")
        weights = replace(weights, sensor_weighting=args.sensor_weighting)
    return weights


def _synthesize_parser() -> ArgumentParser:
    from engine.export_format import TIME_COLUMNS
    from engine.stream.registry import engine_names

    p = ArgumentParser(prog="courtside synthesize", description="Synthesise motion from a recorded take.")
    p.add_argument("--engine", choices=engine_names(), default="motion-graph",
                   help="synthesis engine (engine.stream.registry); every engine but the motion graph runs online "
                        "(as the console) and writes its decided poses: -o OUT.bvh, or OUT.npz (the --save-poses "
                        "format)")
    p.add_argument("--graph", help="graph .npz from build-graph (the motion-graph engine; required for it)")
    p.add_argument("--database", default=None, metavar="FILE",
                   help="--engine other than motion-graph: its database file (OLNG: a knowledge base from "
                        "`courtside reconstruct --save-kb`); default: built from the shipped clips")
    p.add_argument("--input", required=True, help="take .npz (synthesis input format or a gateway export)")
    p.add_argument("-o", "--output", required=True,
                   help="output .bvh (any engine) or .npz (poses; engines other than the motion graph)")
    add_search_args(p)
    p.add_argument("--root-warp", nargs=2, type=float, default=[RootWarp().position_gain, RootWarp().heading_gain],
                   metavar=("GAIN_P", "GAIN_O"),
                   help="pull the root towards the camera by these gains per sample, bounded to human speeds "
                        "(engine/graph/warp.py); 0 0 = seed 000's search")
    p.add_argument("--no-root-fusion", action="store_true",
                   help="keep the chosen path's own (warped) root instead of the camera track smoothed over the lag "
                        "(engine/graph/root_fusion.py)")
    p.add_argument("--lag", type=float, default=None,
                   help="fixed-lag online decoding with this latency (s); on a gateway export this is the console's "
                        "live path itself, so the same lag gives the poses the console showed")
    p.add_argument("--sensor-map", nargs="*", default=None, metavar="STATION/SENSOR=NAME",
                   help="gateway exports: which recorded sensor is which graph sensor")
    p.add_argument("--camera-heading", action="store_true",
                   help="gateway exports: use the tracker's heading as a constraint (off by default, as live: the "
                        "tracker's heading is a rule, not a measurement)")
    p.add_argument("--times", choices=TIME_COLUMNS, default="t_host_s",
                   help="gateway exports: sample times online (as the console saw them; default) or re-fitted offline")
    p.add_argument("--start", type=float, default=None, metavar="T_HOST_S",
                   help="gateway exports: first frame at this gateway time (default: the take's defined first frame, "
                        "0.5 s after recording started, as the console)")
    p.add_argument("--save-poses", default=None, metavar="OUT.npz",
                   help="also save every frame's joint positions (the format `courtside console --save-poses` writes)")
    p.add_argument("--require", nargs="*", default=[], metavar="LABEL@SECONDS",
                   help="human constraints (eq. 8): be on a clip labelled LABEL around this time of the take")
    p.add_argument("--require-tolerance", type=int, default=10, help="+- frames around each required time")
    p.add_argument("--calibration", metavar="RECORD", help="sensor-calibration record (`courtside calibrate` or the "
                   "wizard): readings are rotated from the measured into the graph's nominal sensor mountings, and "
                   "when it calibrated every worn sensor's orientation (a take with quat_wxyz) the worn segments are "
                   "posed with their yaw relative to the pelvis, not only their tilt")
    p.add_argument("--stream-bvh", metavar="[HOST:]PORT", help="also serve the poses as BVH lines over TCP (Axis "
                   "Neuron convention, e.g. 7001; 127.0.0.1 unless a host is given): with --lag each pose as it is "
                   "decided, at the take's rate; without, the written frames")
    p.add_argument("--stream-wait", type=float, default=5.0, help="--stream-bvh: wait this long for a client (s)")
    p.add_argument("--stream-vmc", metavar="[HOST:]PORT", help="also send the poses as VMC (OSC over UDP, e.g. 39539; "
                   "127.0.0.1 unless a host is given) to Unity/Blender/VSeeFace VMC receivers")
    add_quiet_argument(p)
    return p


@dataclass
class DecodedPath:
    """What a motion-graph search decided for a take: the decided poses (frame clock; root, rotations and joints,
    engine.stream.decided) and what the summary line reports."""

    poses: list            # engine.stream.FramePose per frame
    broken_constraints: int = 0
    counts: dict = field(default_factory=dict)  # the live path's statistics (online decoding)


@dataclass(frozen=True)
class Search:
    """How to search: the weights, the root warp towards the camera, the output root's fusion, constraints, and
    the orientation calibration of the graph's sensors (graph order; None: segments posed by tilt only)."""

    weights: SearchWeights
    warp: RootWarp
    fusion: RootFusion
    constraints: list
    orientation_calibration: OrientationCalibration | None = None

    def calibration_of(self, sensor_indices: tuple[int, ...] | None) -> OrientationCalibration | None:
        """The orientation calibration of the searched sensors, in their column order (None: all, graph order)."""
        cal = self.orientation_calibration
        return cal if cal is None or sensor_indices is None else cal.select(sensor_indices)


@cli_command("courtside synthesize")
def synthesize_main(argv: list[str]) -> int:
    """Read the take, decide the path (batch search, or the online decoder with --lag), write BVH and poses."""
    args = _synthesize_parser().parse_args(argv)
    refuse_overwriting_inputs([o for o in (args.output, args.save_poses) if o],
                              [i for i in (args.input, args.graph, args.calibration, args.database) if i])
    if args.engine != "motion-graph":
        return _synthesize_online(args)
    if not args.graph:
        raise CourtsideError("the motion-graph engine needs --graph (from build-graph)")
    graph = MotionGraph.load(args.graph)
    take = _graph_take(args, graph)
    warp = RootWarp(*args.root_warp) if any(args.root_warp) else RootWarp.off()
    weights = weights_from_args(args, warp)
    fusion = RootFusion.off() if args.no_root_fusion else RootFusion()
    warning = coverage_warning(motion_range(graph), take.obs.position_m, take.obs.heading_rad, graph.config.fps)
    if warning:
        print(warning + (" (root warping on: the root follows the camera, the poses stay the database's)"
                         if warp.active else ""), file=sys.stderr)
    constraints = _constraints(args, graph)
    orientation = _orientation_calibration(args, graph)
    stream, outputs = _pose_outputs(args, graph)
    t0 = time.perf_counter()
    decode = _batch_path if args.lag is None else _online_path
    path = decode(args, graph, take, Search(weights, warp, fusion, constraints, orientation), outputs)
    elapsed = time.perf_counter() - t0
    _write_outputs(args, graph, take, path, outputs)
    if stream is not None:
        stream.close()
    counts = path.counts
    print(json.dumps({"samples": int(take.obs.n_samples), "first_frame": int(take.frame[0]),
                      "search_s": round(elapsed, 3), "output": args.output,
                      "broken_constraints": path.broken_constraints,
                      "segment_posing": _segment_posing(graph, weights, take.obs.quat_wxyz is not None, orientation),
                      **{k: counts[k] for k in ("confidence_mean", "reanchors") if k in counts}}))
    return 0


def _graph_take(args: argparse.Namespace, graph: MotionGraph):
    """The take on the graph's frame clock (engine.graph.inputs.TakeFrames), its readings rotated into the graph's
    nominal mountings with --calibration; refuses what the graph cannot decode (no skeleton, a take longer than
    its longest path)."""
    from .inputs import read_take

    sensor_map = parse_sensor_map(args.sensor_map, graph.config.sensor_names)
    check_lag(args.lag, graph.config.fps)
    check_output_dir(args.output)
    take = read_take(args.input, graph.config.sensor_names, graph.config.fps, sensor_map,
                     use_camera_heading=args.camera_heading, times=args.times, start_s=args.start)
    if args.calibration and graph.skeleton is not None:
        from .calibrated_input import calibrated_take

        try:
            take = calibrated_take(take, graph.skeleton, graph.config.sensor_names, args.calibration)
        except ValueError as exc:  # a record made for another skeleton's joint frames
            raise MalformedFileError(args.calibration, None, str(exc)) from None
    if graph.skeleton is None:
        raise MalformedFileError(args.graph, None, "graph holds no skeleton (rebuild it with build-graph)")
    check_path_length(args.graph, graph.edge_src, graph.edge_dst, graph.n_nodes, take.obs.n_samples,
                      graph.config.fps)
    return take


def _orientation_calibration(args: argparse.Namespace, graph: MotionGraph) -> OrientationCalibration | None:
    """--calibration's orientation calibration of the graph's sensors (None without a record, or when some
    worn sensor's orientation was not calibrated: then a note says the segments are posed by tilt only)."""
    if not args.calibration:
        return None
    cal = load_sensor_calibration(args.calibration).orientation_calibration(graph.config.sensor_names)
    if cal is None:
        print(f"note: {args.calibration}: not every graph sensor's orientation is calibrated (the record's still "
              "capture had no orientations from some): worn segments are posed by their tilt only", file=sys.stderr)
    return cal


def _segment_posing(graph: MotionGraph, weights: SearchWeights, has_orientations: bool,
                    calibration: OrientationCalibration | None) -> str | None:
    """How the worn segments were posed (orientation_pose.SegmentPosing), for the summary line."""
    if weights.segment_pose <= 0 or not places_sensors(graph):
        return None
    if has_orientations:
        return "calibrated yaw" if calibration is not None else "tilt only"
    return "tilt from accelerations" if weights.tilt_from_acc_s > 0 and calibration is None else None


def _constraints(args: argparse.Namespace, graph: MotionGraph) -> list:
    """--require LABEL@SECONDS as search constraints (eq. 8); the batch search only."""
    from . import label_constraint

    try:
        constraints = [label_constraint(graph, r.rsplit("@", 1)[0], int(round(float(r.rsplit("@", 1)[1])
                                                                                * graph.config.fps)),
                                        args.require_tolerance) for r in args.require]
    except (KeyError, ValueError, IndexError) as exc:
        raise CourtsideError(f"bad --require {args.require}: {exc}") from None
    if constraints and args.lag is not None:
        raise CourtsideError("--require needs the batch search (no --lag)")
    return constraints


def _pose_outputs(args: argparse.Namespace, graph: MotionGraph) -> tuple:
    """(the BVH server to close at the end or None, every pose output: --stream-bvh, --stream-vmc)."""
    stream, outputs = None, []
    if args.stream_bvh:
        from engine.livestream.stream_cli import open_stream

        stream = open_stream(args.stream_bvh, args.stream_wait)
        outputs.append(stream)
    if args.stream_vmc:
        from engine.livestream.stream_cli import open_vmc

        outputs.append(open_vmc(args.stream_vmc, graph.skeleton))
    return stream, outputs


def _batch_path(args: argparse.Namespace, graph: MotionGraph, take, search: Search, outputs: list) -> DecodedPath:
    """The whole take searched at once; the output root fused from the camera over the whole take."""
    from engine.stream import FramePose

    from .orientation_pose import SegmentPosing, decided_path_poses
    from .root_fusion import fuse_track
    from .search import ViterbiSearch

    indices, fps = _columns(graph, take.obs), graph.config.fps
    calibration = search.calibration_of(indices)
    obs = replace(take.obs, orientation_calibration=calibration)  # the search's orientation term reads it too
    res = ViterbiSearch(graph, search.weights, warp=search.warp).run(obs, search.constraints)
    ground, heading = fuse_track(search.fusion, fps, obs.position_m, obs.heading_rad, res.ground_m, res.heading_rad)
    posing = SegmentPosing.for_search(graph, indices, search.weights, calibration)
    decided = decided_path_poses(graph, res.nodes, res.blend_nodes, ground, heading, posing, obs.acc_g,
                                 obs.quat_wxyz)
    poses = [FramePose(int(f), int(f) / fps, decided.joint_positions_m[i], root_m=decided.root_m[i],
                       local_rotations=decided.local_rotations[i]) for i, f in enumerate(take.frame)]
    return DecodedPath(poses, res.broken_constraints)


def _online_path(args: argparse.Namespace, graph: MotionGraph, take, search: Search, outputs: list) -> DecodedPath:
    """The fixed-lag decoder, sample by sample: a gateway take through the console's own live path, a
    synthesis-input take frame by frame (engine.stream); each pose streamed as it is decided."""
    from engine.stream import synthesize_streams
    from engine.stream.offline import drive_take

    from .online import FixedLagSynthesizer

    obs, fps = take.obs, graph.config.fps
    indices, acc = obs.sensor_indices, obs.acc_g
    if take.streams is None and indices is not None and acc is not None:  # frames in the graph's sensor order,
        order = np.argsort(indices)  # as drive_take orders the orientations
        indices, acc = tuple(int(i) for i in np.asarray(indices)[order]), acc[:, order]
    made = []

    def make():
        syn = FixedLagSynthesizer(graph, args.lag, search.weights, indices, warp=search.warp, fusion=search.fusion,
                                  orientation_calibration=search.calibration_of(indices))
        if outputs:  # each pose goes out as the decoder commits to it, at the take's rate
            from engine.livestream.poses import PoseStreamer, StreamingSynthesizer

            syn = StreamingSynthesizer(syn, PoseStreamer(graph.skeleton, graph.config.fps, outputs, realtime=True))
        made.append(syn)
        return syn

    counts: dict = {}
    if take.streams is not None:  # a gateway take: the live path, sample by sample
        poses, session = synthesize_streams(make, take.streams, take.stream_keys, fps, start_s=args.start,
                                            use_camera_heading=args.camera_heading)
        counts = vars(session.stats)
    else:
        poses = drive_take(make(), acc, obs, int(take.frame[0]), fps)
    counts.update(confidence_mean=round(float(np.mean([q.confidence for q in poses])), 3) if poses else None,
                  reanchors=len(made[-1].reanchors))
    return DecodedPath(poses, counts=counts)


def _columns(graph: MotionGraph, obs) -> tuple[int, ...]:
    """The graph sensor of each of the take's observation columns."""
    return tuple(obs.sensor_indices) if obs.sensor_indices is not None else tuple(range(graph.n_sensors))


def _write_outputs(args: argparse.Namespace, graph: MotionGraph, take, path: DecodedPath, outputs: list) -> None:
    """The BVH of the decided poses (the poses the console shows and --save-poses keeps: one pose everywhere),
    the batch search's frames to the pose outputs, --save-poses."""
    from engine.stream.decided import poses_to_motion
    from engine.stream.poses_file import save_poses

    motion = poses_to_motion(graph.skeleton, graph.config.fps, path.poses, name=Path(args.input).stem)
    write_bvh(args.output, motion)
    if outputs and args.lag is None:  # the batch search decides the whole path at once: stream the written frames
        from engine.livestream.stream_cli import stream_motion

        stream_motion(outputs, motion)
    if args.save_poses:
        poses = path.poses
        save_poses(args.save_poses, poses, graph.skeleton.parents,
                   {"engine": "motion-graph", "database": str(args.graph), "lag_s": args.lag,
                    "rate_hz": graph.config.fps, "start_frame": int(poses[0].frame) if poses else None,
                    "input": str(args.input), "use_camera_heading": args.camera_heading, **path.counts})


def _synthesize_online(args: argparse.Namespace) -> int:
    """`courtside synthesize --engine NAME` for an engine other than the motion graph: its spec from the registry
    (a --database file, else the shipped clips), the take through the live path, the decided poses written to -o:
    a BVH of their rotations (whose forward kinematics are the saved joints), or the poses file."""
    from engine.stream.decided import has_rotations, poses_to_motion
    from engine.stream.offline import synthesize_take
    from engine.stream.poses_file import save_poses
    from engine.stream.registry import adapter

    to_bvh = args.output.lower().endswith(".bvh")
    if not to_bvh and not args.output.lower().endswith(".npz"):
        raise CourtsideError(f"-o {args.output}: --engine {args.engine} writes OUT.bvh or its poses as OUT.npz")
    check_output_dir(args.output)
    module = adapter(args.engine)
    if args.database is not None and module.load_spec is None:
        raise CourtsideError(f"--database: the {args.engine} engine has no database file (it builds its own)")
    spec = module.shipped_spec() if args.database is None else module.load_spec(args.database)
    lag = 0.0 if args.lag is None else args.lag
    check_lag(lag, spec.rate_hz)
    t0 = time.perf_counter()
    poses = synthesize_take(spec, args.input, lag, sensor_map=parse_sensor_map(args.sensor_map, spec.sensor_names),
                            use_camera_heading=args.camera_heading, times=args.times, start_s=args.start)
    elapsed = time.perf_counter() - t0
    meta = {"engine": spec.name, "database": spec.database, "lag_s": lag, "rate_hz": spec.rate_hz,
            "start_frame": int(poses[0].frame) if poses else None, "input": str(args.input),
            "use_camera_heading": args.camera_heading}
    if to_bvh and not has_rotations(poses):
        raise CourtsideError(f"-o {args.output}: the {spec.name} engine decided no poses with joint rotations for "
                             "this take; give -o OUT.npz")
    if to_bvh:
        write_bvh(args.output, poses_to_motion(spec.skeleton, spec.rate_hz, poses, Path(args.input).stem))
    else:
        save_poses(args.output, poses, spec.parents, meta)
    if args.save_poses:
        save_poses(args.save_poses, poses, spec.parents, meta)
    print(json.dumps({"engine": spec.name, "frames": len(poses), "search_s": round(elapsed, 3),
                      "output": args.output}))
    return 0


@cli_command("courtside evaluate")
def evaluate_main(argv: list[str]) -> int:
    from .evaluate import Setting, graph_leave_one_out, summarise

    p = ArgumentParser(prog="courtside evaluate",
                       description="Leave-one-out evaluation (seed 000 Tables 2/3) on real mocap.")
    p.add_argument("clips", nargs="*", help=".bvh or .amc files (one skeleton)")
    _add_database_args(p)
    p.add_argument("--variants", default="plain,msv", help="comma list of plain, msv, interp, msv+interp")
    p.add_argument("--test-clips", type=int, default=0, help="evaluate on N clips spread over the set (0 = all)")
    p.add_argument("--seed", type=int, default=0)
    add_quiet_argument(p)
    args = p.parse_args(argv)
    if not (args.clips or args.sample or args.mocap_dir):
        args.sample = True
    variants = args.variants.split(",")
    full = GraphConfig(msv="msv" in args.variants, interp="interp" in args.variants,
                       transition_threshold_m=args.threshold)
    motions, clips, sensor_model = load_clips(args, full)
    idx = {n: args.sensors.index(n) for n in args.sensors}
    all_s = tuple(range(len(args.sensors)))
    two = tuple(idx[n] for n in ("left_forearm", "right_forearm") if n in idx)
    one = tuple(idx[n] for n in ("right_forearm",) if n in idx)
    acc, ph, both = SearchWeights(0.5, 0, 0), SearchWeights(0, 1, 1), SearchWeights(0.5, 1, 1)
    settings = [Setting(f"acc {len(all_s)}", all_s, acc), Setting(f"acc {len(two)}", two, acc),
                Setting(f"acc {len(one)}", one, acc), Setting("pos+head", (), ph),
                Setting(f"acc {len(all_s)} + pos+head", all_s, both), Setting(f"acc {len(two)} + pos+head", two, both),
                Setting(f"acc {len(one)} + pos+head", one, both)]
    n = len(clips)
    tests = list(range(n)) if not args.test_clips else sorted(set(np.linspace(0, n - 1, args.test_clips).astype(int)))
    print("action % = frames whose synthesised pose comes from a clip with the test clip's label "
          "(Bandai content: walk, run, punch, kick, ...)")
    print(f"database: {n} clips, {sum(c.n_frames for c in clips)} frames at {full.fps:g} Hz; "
          f"test clips: {len(tests)}; sensors: {', '.join(args.sensors)}")
    header = f"{'graph':12s} {'nodes':>7s} {'edges':>8s}  {'input':22s} {'joint cm (sd)':>14s} " \
             f"{'position cm (sd)':>17s} {'heading deg (sd)':>17s} {'action %':>8s} {'search s':>8s}"
    print(header)
    print("-" * len(header))
    for v in variants:
        cfg = GraphConfig(msv="msv" in v, interp="interp" in v, transition_threshold_m=args.threshold,
                          sensor_names=list(args.sensors))
        graph = build_from_clips(clips, cfg, sensor_model)
        t0 = time.perf_counter()
        scores = graph_leave_one_out(graph, clips, motions[0].skeleton, settings, tests, seed=args.seed)
        per = (time.perf_counter() - t0) / len(settings)
        for s in settings:
            r = summarise(scores[s.name])
            print(f"{v:12s} {graph.n_nodes:7d} {graph.n_edges:8d}  {s.name:22s} "
                  f"{r['joint_cm']:6.1f} ({r['joint_sd']:4.1f}) {r['pos_cm']:8.1f} ({r['pos_sd']:5.1f}) "
                  f"{r['head_deg']:8.1f} ({r['head_sd']:5.1f}) {r['label_pct']:8.1f} {per:8.1f}")
    return 0
