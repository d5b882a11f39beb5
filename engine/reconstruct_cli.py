"""`courtside reconstruct`: full-body motion from worn sensors by one of three methods, or the common table.

    courtside reconstruct --method olng --input take.npz -o out.bvh --sample
    courtside reconstruct --method hmm --input take.npz -o out.bvh --sample
    courtside reconstruct --method motion-graph --input take.npz -o out.bvh --graph graph.npz
    courtside reconstruct --evaluate --sample [--methods olng,hmm,motion-graph] [--test-clips 3]

The database comes from clip files, `--sample` (CMU subject 16 clips shipped in engine/data) or
`--mocap-dir DIR --pattern GLOB`; `--save-kb`/`--kb` store and reuse a built OLNG knowledge base.
Takes are the synthesis-input .npz or a gateway export (read by engine.graph.inputs.load_take). OLNG and the HMM
run as their live engines (engine/olng/online_engine.py, engine/hmm/online_engine.py) and the BVH is the poses
they decide, as the console draws them and `--save-poses` saves them.
"""
from __future__ import annotations

import argparse
import glob
import json
import sys
import time
from pathlib import Path

import numpy as np

from engine import progress
from engine.atomic_write import refuse_overwriting_inputs
from engine.errors import ArgumentParser, CourtsideError, MalformedFileError, cli_command
from engine.stream.offline import acc_in_sensor_order

SAMPLE_PREFIX = "16_"


def _database_paths(args: argparse.Namespace) -> list[Path]:
    from engine.mocap import sample_clips

    paths = [Path(p) for p in args.clips]
    if args.sample:
        paths += [p for name, p in sample_clips().items() if name.startswith(SAMPLE_PREFIX)]
    if args.mocap_dir:
        paths += [Path(p) for p in sorted(glob.glob(str(Path(args.mocap_dir) / args.pattern)))]
    if not paths:
        raise CourtsideError("no clips: give clip files, --sample, or --mocap-dir with --pattern")
    return paths


def _olng_config(args: argparse.Namespace):
    from engine.olng.config import NeighbourhoodGraphConfig, OLNGConfig

    return OLNGConfig(graph=NeighbourhoodGraphConfig(k_neighbours=args.k, i_best=args.i_best, window=args.window))


def _load_motions(args: argparse.Namespace):
    from engine.mocap import load_database

    return load_database(_database_paths(args), fps=args.fps)


def _olng_knowledge_base(args: argparse.Namespace):
    from engine.olng.config import KnowledgeBaseConfig
    from engine.olng.knowledge_base import KnowledgeBase
    from engine.olng.mocap_bridge import build_knowledge_base

    if args.kb:
        return KnowledgeBase.load(args.kb)
    kb = build_knowledge_base(_load_motions(args), KnowledgeBaseConfig(mirror=args.mirror, reverse=args.reverse))
    if args.save_kb:
        kb.save(args.save_kb)
    return kb


def _reconstruct_olng(args: argparse.Namespace) -> dict:
    from engine.graph.inputs import load_take
    from engine.mocap import SEED003_SENSORS
    from engine.olng.online_engine import OLNGEngine

    kb = _olng_knowledge_base(args)
    obs = load_take(args.input, list(SEED003_SENSORS), kb.fps)
    acc = acc_in_sensor_order(args.input, obs, len(SEED003_SENSORS),
                              f"the OLNG needs all four sensors {list(SEED003_SENSORS)}")
    engine = OLNGEngine(kb, config=_olng_config(args))
    return _write_decided(args, engine, kb.fps, acc, obs)


def _reconstruct_hmm(args: argparse.Namespace) -> dict:
    """The paper's acc + gyro model trained on the clips, run as the live engine runs it (`HMMEngine`)."""
    from engine.graph.inputs import read_take
    from engine.hmm.evaluation import train_model
    from engine.hmm.online_engine import HMMEngine

    motions = _load_motions(args)
    model = train_model(motions, imu_names=tuple(args.imus))
    take = read_take(args.input, list(args.imus), model.fps)
    acc = acc_in_sensor_order(args.input, take.obs, len(args.imus), f"the HMM needs the IMUs {args.imus}")
    gyro = _take_gyro(args.input, take.frame, model.fps, list(args.imus))
    engine = HMMEngine({model.config.imu_channels: model}, motions[0].skeleton)
    return _write_decided(args, engine, model.fps, acc, take.obs, gyro)


def _write_decided(args: argparse.Namespace, engine, fps: float, acc: np.ndarray, obs,
                   gyro_rps: np.ndarray | None = None) -> dict:
    """Push the take through ``engine`` (`drive_frames`, the loop every driver uses) and write its decided poses
    (rotations of ``engine.skeleton``) as the BVH: the file is the poses the console and `--save-poses` show
    (issue 29), nothing applied after."""
    from engine.mocap import write_bvh
    from engine.stream.decided import poses_to_motion
    from engine.stream.engines import drive_frames

    cam_pos, cam_head = _camera(obs, len(acc))
    t0 = time.perf_counter()
    poses = drive_frames(engine, acc, cam_pos, cam_head, gyro_rps=gyro_rps)
    elapsed = time.perf_counter() - t0
    write_bvh(args.output, poses_to_motion(engine.skeleton, fps, poses, Path(args.input).stem))
    return {"frames": len(poses), "seconds": round(elapsed, 3), "fps": round(len(poses) / max(elapsed, 1e-9), 1)}


def _camera(obs, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The take's camera track for its first n samples (ground position (n, 2) m, heading (n,) rad; NaN rows where
    it has none): OLNG and the HMM pull their integrated root onto it (engine/graph/warp.py)."""
    pos = np.full((n, 2), np.nan) if obs.position_m is None else np.asarray(obs.position_m, float)[:n]
    head = np.full(n, np.nan) if obs.heading_rad is None else np.asarray(obs.heading_rad, float)[:n]
    return pos, head


def _take_gyro(path: str, frames: np.ndarray, fps: float, imus: list[str]) -> np.ndarray:
    """`gyro_rps` (T, S, 3) rad/s of the model's IMUs from the take (the HMM's IMU feature is acc + gyro), on the
    same frames as the accelerations (`engine.stream.resample_uniform`, the one sample -> frame path); a take
    naming its sensors (`sensor_names`, e.g. from `courtside import-imu`) may hold more."""
    from engine.graph.input_checks import open_npz
    from engine.stream import resample_uniform

    with open_npz(Path(path)) as data:
        if "gyro_rps" not in data.files:
            raise MalformedFileError(path, None, "the HMM method needs 'gyro_rps' (T, S, 3) rad/s beside 'acc_g'")
        gyro = np.asarray(data["gyro_rps"], float)
        if "sensor_names" in data.files:
            names = [str(n) for n in data["sensor_names"]]
            gyro = gyro[:, [names.index(n) for n in imus if n in names]]
        take_fps = float(data["fps"])
    gyro = resample_uniform(gyro, take_fps, fps)
    rows = np.searchsorted(gyro.index, frames)
    if len(gyro) == 0 or np.any(rows >= len(gyro)) or not np.array_equal(gyro.index[np.minimum(rows, len(gyro) - 1)], frames):
        raise MalformedFileError(path, None, f"gyro_rps does not cover the acc_g frames at {fps:g} Hz")
    return gyro.acc_g[rows]


def _reconstruct_motion_graph(args: argparse.Namespace) -> int:
    from engine.graph.cli import synthesize_main

    if not args.graph:
        raise CourtsideError("--method motion-graph needs --graph (from `courtside build-graph`)")
    return synthesize_main(["--graph", args.graph, "--input", args.input, "-o", args.output])


def _evaluate(args: argparse.Namespace) -> int:
    from engine.olng.metrics import format_table, summarise

    motions = _load_motions(args)
    n = len(motions)
    tests = sorted(set(np.linspace(0, n - 1, args.test_clips).astype(int))) if args.test_clips else list(range(n))
    print(f"database: {n} clips; held-out test clips: {', '.join(motions[i].name for i in tests)}; "
          f"sensor noise: {args.noise}")
    rows: dict[str, dict[str, float]] = {}
    methods = args.methods.split(",")
    error_model = None
    if args.noise == "seed000":
        from engine.mocap import SensorErrorModel

        error_model = SensorErrorModel.seed000()
    if "olng" in methods:
        from engine.olng.config import EnergyConfig, KnowledgeBaseConfig, NeighbourhoodGraphConfig, OLNGConfig
        from engine.olng.evaluation import Variant, mean_pose_baseline, olng_leave_one_out

        base = _olng_config(args)
        variants = [Variant("olng (4 acc)", base),
                    Variant("olng mahalanobis prior", OLNGConfig(graph=base.graph, energy=EnergyConfig(kernel="mahalanobis"))),
                    Variant("olng no time warp", OLNGConfig(graph=NeighbourhoodGraphConfig(
                        k_neighbours=args.k, i_best=args.i_best, window=args.window, max_column_step=1, max_warp=1)))]
        if args.orientations:  # issue 18: the channels a real IMU streams, orientations through a realistic filter
            variants += [Variant("olng (4 acc + orientation)", base, ("acc", "orientation")),
                         Variant("olng (4 acc + ori + gyro)", base, ("acc", "orientation", "gyro"))]
        kb_config = KnowledgeBaseConfig(mirror=args.mirror, reverse=args.reverse)
        scores = olng_leave_one_out(motions, tests, variants, kb_config, error_model, seed=args.seed)
        rows.update({k: summarise(v) for k, v in scores.items()})
        rows["database mean pose"] = summarise(mean_pose_baseline(motions, tests, kb_config))
    if "hmm" in methods:
        from engine.hmm.config import HMMConfig
        from engine.hmm.evaluation import hmm_leave_one_out

        for imus in (("right_foot",), ("right_foot", "right_wrist")):
            scores = hmm_leave_one_out(motions, tests, imu_names=imus, error_model=error_model, seed=args.seed)
            rows[f"hmm ({len(imus)} imu)"] = summarise(scores)
            if args.orientations:  # acc only, and with the tilt of a realistic filter, beside the paper's acc + gyro
                for channels in ("acc", "acc+gyro+tilt"):
                    scores = hmm_leave_one_out(motions, tests, imu_names=imus, error_model=error_model,
                                               seed=args.seed, config=HMMConfig(imu_channels=channels))
                    rows[f"hmm ({len(imus)} imu, {channels})"] = summarise(scores)
    if "motion-graph" in methods:
        rows.update(_motion_graph_rows(args, motions, tests))
    print(format_table(rows))
    return 0


def _motion_graph_rows(args: argparse.Namespace, motions, tests) -> dict[str, dict[str, float]]:
    """engine.graph's own leave-one-out on the same clips, acc-only with the seed-003 sensors."""
    from engine.graph.config import GraphConfig
    from engine.graph.evaluate import Setting, graph_leave_one_out, summarise
    from engine.graph.graph import build_from_clips
    from engine.graph.mocap_adapter import clips_from_motions
    from engine.graph.viterbi import SearchWeights
    from engine.mocap import SEED003_SENSORS, resample, standard_placements

    config = GraphConfig(sensor_names=list(SEED003_SENSORS))
    at_rate = [resample(m, config.fps) for m in motions]
    clips = clips_from_motions(at_rate, standard_placements(at_rate[0].skeleton, SEED003_SENSORS), config)
    graph = build_from_clips(clips, config)
    setting = Setting("acc 4", tuple(range(len(SEED003_SENSORS))), SearchWeights(0.5, 0, 0))
    scores = graph_leave_one_out(graph, clips, at_rate[0].skeleton, [setting], tests, seed=args.seed)
    return {"motion graph (4 acc)": summarise(scores[setting.name])}


def build_parser() -> argparse.ArgumentParser:
    p = ArgumentParser(prog="courtside reconstruct", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("clips", nargs="*", help="database clips (.bvh or .amc, one skeleton)")
    p.add_argument("--method", choices=["olng", "hmm", "motion-graph"], default="olng",
                   help="olng: four wrist/ankle accelerometers; hmm: one or two IMUs with gyroscopes; motion-graph: "
                        "courtside synthesize on --graph")
    p.add_argument("--input", help="take .npz")
    p.add_argument("-o", "--output", help="output .bvh")
    p.add_argument("--evaluate", action="store_true", help="leave-one-out table instead of reconstructing a take")
    p.add_argument("--methods", default="olng,hmm", help="--evaluate: comma list of olng, hmm, motion-graph")
    p.add_argument("--test-clips", type=int, default=3, help="--evaluate: N clips spread over the set (0 = all)")
    p.add_argument("--noise", choices=["clean", "seed000"], default="clean", help="--evaluate: sensor error model")
    p.add_argument("--orientations", action="store_true",
                   help="--evaluate: add rows searching on orientation (realistic filter: per-sensor yaw, drift, tilt "
                        "noise, misalignment) and angular rate, and the HMM's accelerometer-only model")
    p.add_argument("--seed", type=int, default=0, help="--evaluate: seed of the simulated sensor errors")
    p.add_argument("--sample", action="store_true", help="use the CMU subject-16 clips shipped in engine/data")
    p.add_argument("--mocap-dir", help="a mocap folder, e.g. ../shared/mocap")
    p.add_argument("--pattern", default="cmu-amc/16/*.amc", help="glob under --mocap-dir")
    p.add_argument("--fps", type=float, default=30.0, help="rate the clips are loaded at (each method resamples)")
    p.add_argument("--kb", help="olng: load this knowledge base .npz instead of building one")
    p.add_argument("--save-kb", help="olng: save the built knowledge base here")
    p.add_argument("--mirror", action="store_true", help="olng: add mirrored clips (needs a symmetric rest pose)")
    p.add_argument("--reverse", action="store_true", help="olng: add time-reversed clips")
    p.add_argument("--k", type=int, default=512, help="olng: neighbours per frame (paper: 4096 for 500k frames)")
    p.add_argument("--i-best", type=int, default=32, help="olng: hypotheses per frame (paper: 256)")
    p.add_argument("--window", type=int, default=32, help="olng: OLNG window M (frames)")
    p.add_argument("--imus", nargs="+", default=["right_foot"], help="hmm: worn IMUs (standard sensor names)")
    progress.add_quiet_argument(p)
    p.add_argument("--graph", help="motion-graph: graph .npz from `courtside build-graph`")
    return p


@cli_command("courtside reconstruct")
def main(argv: list[str]) -> int:
    args = build_parser().parse_args(argv)
    if args.evaluate:
        return _evaluate(args)
    if not args.input or not args.output:
        raise CourtsideError("--input and -o are required (or use --evaluate)")
    refuse_overwriting_inputs([args.output], [args.input, *args.clips])
    if args.method == "motion-graph":
        return _reconstruct_motion_graph(args)
    summary = _reconstruct_olng(args) if args.method == "olng" else _reconstruct_hmm(args)
    print(json.dumps({"method": args.method, "output": args.output, **summary}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
