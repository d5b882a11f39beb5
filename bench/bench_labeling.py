"""Seed 001 benchmark: online labeling accuracy and speed vs closest-point tracking, on real marker data.

Tables (each baseline measured in the same run on the same degraded stream; frames/s from CPU time,
so other processes on a shared machine distort them less):
  0. every shared real take (the labelled C3D files and the jyu Qualisys recordings), exactly as
     `courtside label FILE --degrade 1` scores it (engine.labeling.evaluation): accuracy overall and per 10 s,
     re-acquisition time after a forced 0.5 s loss of one rigid body every 10 s, recovered-marker error, and the
     closest-point baseline; then the full pipeline (label → fit-skeleton → BVH → build-graph) on the long CMU
     take cmu_85_12 (the test suite runs it on a 15 s slice);
  1. two-player tennis serve (real, 2 x 39 markers, 50 Hz), players slid to 0.6 m after training;
  2. two CMU subjects (real 41-marker trials, 120 Hz) brought together, at 120 / 60 / 30 fps (paper Exp. 1);
  3. scaling: the tennis players replicated to 2..10 subjects on a 1.2 m grid, frames/s per subject count.

    .venv/bin/python bench/bench_labeling.py [--mocap /work/shared/mocap] [--quick] [--only-takes] [--seeds 1,2,3]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.io import loadmat

from engine.labeling.baseline import ClosestPointTracker
from engine.labeling.cli import subjects_of
from engine.labeling.config import LabelingConfig
from engine.labeling.evaluation import default_train_frames, evaluate_take
from engine.labeling.labeler import RECOVERED, OnlineLabeler
from engine.labeling.scenario import DegradeConfig, Score, bring_together, degrade, score_frame
from engine.mocap import MarkerData, read_c3d

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench.support.shared_data import find_shared_mocap  # noqa: E402  (one place that knows where the shared data lives)


def label_stream(positions, subjects, fps, train, config, seed=0):
    """Degrade, train, label. Returns (stream, labeler, results, frames/s from CPU time)."""
    stream = degrade(positions, subjects, DegradeConfig(protect_frames=train), np.random.default_rng(seed))
    labeler = OnlineLabeler(config)
    labeler.train(positions[:train], subjects, fps)
    start = time.process_time()
    results = [labeler.step(cloud) for cloud in stream.clouds[train:]]
    return stream, labeler, results, len(results) / (time.process_time() - start)


def recovery_breakdown(stream, labeler, results, train):
    """Paper Fig. 8 metric: recovered-marker error / largest pair distance of its body, by frames into the gap
    and by how many markers of the body are missing. Returns {bin name: (median relative error, samples)}."""
    visible = stream.visible
    age = np.zeros(visible.shape, int)  # frames since the label disappeared
    for t in range(1, len(visible)):
        age[t] = np.where(visible[t], 0, age[t - 1] + 1)
    body_of = np.empty(visible.shape[1], int)
    extent = np.zeros(visible.shape[1])
    for b, body in enumerate(labeler.bodies):
        body_of[body] = b
        pts = stream.clean_m[train - 1, body]
        extent[body] = np.max(np.linalg.norm(pts[:, None] - pts[None], axis=2))
    bins: dict[str, list[float]] = {}
    for t, r in enumerate(results, start=train):
        hidden = ~visible[t]
        missing_in_body = np.bincount(body_of[hidden], minlength=len(labeler.bodies))[body_of]
        for label in np.flatnonzero(hidden & (r.status == RECOVERED)):
            rel = np.linalg.norm(r.positions_m[label] - stream.clean_m[t, label]) / extent[label]
            gap = "gap 1-5" if age[t, label] <= 5 else "gap 6-10" if age[t, label] <= 10 else "gap 11-20"
            body = f"{min(missing_in_body[label], 3)}{'+' if missing_in_body[label] >= 3 else ''} missing in body"
            bins.setdefault(gap, []).append(rel)
            bins.setdefault(body, []).append(rel)
    order = ["gap 1-5", "gap 6-10", "gap 11-20", "1 missing in body", "2 missing in body", "3+ missing in body"]
    return {k: (float(np.median(bins[k])), len(bins[k])) for k in order if k in bins}


def run_case(positions, subjects, fps, train, config, seed=0, baselines=True):
    """Label one degraded stream; returns a dict of scores and frames/s for ours and both baselines."""
    stream, labeler, results, ours_fps = label_stream(positions, subjects, fps, train, config, seed)
    ours, cands = Score(), []
    for t, r in enumerate(results, start=train):
        cands.append(r.mean_candidates)
        score_frame(ours, stream, t, r.label_point, np.where((r.status == RECOVERED)[:, None], r.positions_m, np.nan))
    row = {"acc": ours.accuracy, "false": ours.false / max(ours.total, 1), "missed": ours.missed / max(ours.total, 1),
           "swaps": ours.swaps, "fps": ours_fps, "cands": float(np.mean(cands)),
           "rec_mm": 1000 * float(np.median(ours.recovery_err_m)) if ours.recovery_err_m else float("nan"),
           "bodies": sorted(len(b) for b in labeler.bodies)}
    if baselines:
        for name, one_to_one in (("hung", True), ("naive", False)):
            tracker, score = ClosestPointTracker(positions[train - 1], one_to_one), Score()
            start = time.process_time()
            picks = [tracker.step(cloud) for cloud in stream.clouds[train:]]
            row[f"{name}_fps"] = len(picks) / (time.process_time() - start)
            for t, lp in enumerate(picks, start=train):
                score_frame(score, stream, t, lp)
            row[f"{name}_acc"], row[f"{name}_swaps"] = score.accuracy, score.swaps
    return row


def _print(title, rows):
    print(f"\n{title}")
    print(f"{'case':<22}{'acc':>7}{'false':>7}{'miss':>7}{'swaps':>7}{'cand':>6}{'rec_mm':>8}{'fps':>8}"
          f"{'hung_acc':>9}{'hung_sw':>8}{'hung_fps':>9}{'naive_acc':>10}")
    for name, r in rows:
        print(f"{name:<22}{r['acc']:>7.3f}{r['false']:>7.3f}{r['missed']:>7.3f}{r['swaps']:>7d}{r['cands']:>6.2f}"
              f"{r['rec_mm']:>8.1f}{r['fps']:>8.0f}{r.get('hung_acc', np.nan):>9.3f}{r.get('hung_swaps', 0):>8d}"
              f"{r.get('hung_fps', np.nan):>9.0f}{r.get('naive_acc', np.nan):>10.3f}")


def tennis(mocap: Path):
    data = read_c3d(mocap / "markers" / "ktk_kinematics_tennis_serve_2players.c3d")
    subjects = subjects_of(data.labels)
    return data, subjects, bring_together(data.positions_m, subjects, 1, 0.6, 150, 50)


UNLABELLED = ("clouthier_S01_Pronetokneel01_mksrem", "clouthier_S09_KneeltoRun02")  # "*N" fragment ids: no truth


def real_takes(mocap: Path) -> list[MarkerData]:
    """Every shared real take with marker names (C3D files; the jyu Qualisys dance and walk recordings)."""
    takes = [read_c3d(p) for p in sorted((mocap / "markers").glob("*.c3d")) if p.stem not in UNLABELLED]
    mat = loadmat(mocap / "jyu-markers" / "mcdemodata.mat", squeeze_me=True, struct_as_record=False)
    for key in ("dance1", "dance2", "walk1", "walk2"):
        rec = mat[key]
        positions = 0.001 * np.asarray(rec.data, float).reshape(int(rec.nFrames), int(rec.nMarkers), 3)
        positions[(positions == 0).all(axis=2)] = np.nan  # the toolbox stores a missing sample as zeros
        takes.append(MarkerData(tuple(str(n) for n in rec.markerName), positions, float(rec.freq), f"jyu_{key}"))
    return takes


def takes_table(mocap: Path, seeds: tuple[int, ...] = (1,)) -> None:
    """Table 0: one row per take and degrade seed, each exactly what `courtside label FILE --degrade SEED` prints;
    then, with several seeds, the worst and mean accuracy per take over the seeds beside the baseline's mean."""
    print("\n0. every shared real take, as `courtside label FILE --degrade SEED` scores it (train 10 s, at most half "
          "the take; one rigid body removed for 0.5 s every 10 s)")
    print(f"{'take':<36}{'seed':>5}{'frames':>7}{'Hz':>5}{'acc':>7}{'base':>7}{'obs':>6}{'rec':>6}{'lost':>6}"
          f"{'rec_mm':>8}{'fps':>6}  {'re-acq s (median/max)':<22}accuracy per 10 s")
    summary = []
    for data in real_takes(mocap):
        subjects = subjects_of(data.labels)
        train = default_train_frames(data.n_frames, data.fps)
        accs, bases, reacqs = [], [], []
        for seed in seeds:
            ev, _, _ = evaluate_take(data, subjects, LabelingConfig(train_frames=train), seed)
            reacq = np.array(ev.reacquire_s)
            reacqs.extend(ev.reacquire_s)
            accs.append(ev.score.accuracy)
            bases.append(ev.baseline.accuracy)
            cell = (f"{np.median(reacq):.2f} / {np.max(reacq):.2f}" if len(reacq) else "-").replace("inf", "never")
            print(f"{data.name:<36}{seed:>5}{data.n_frames:>7}{data.fps:>5.0f}{ev.score.accuracy:>7.3f}"
                  f"{ev.baseline.accuracy:>7.3f}" + "".join(f"{f:>6.3f}" for f in ev.status_fractions)
                  + f"{ev.recovered_error_mm:>8.1f}{ev.frames_per_s:>6.0f}  {cell:<22}"
                  + " ".join(f"{a:.2f}" for a in ev.window_accuracy), flush=True)
        summary.append((data.name, accs, bases, reacqs))
    print(f"not scored: {', '.join(UNLABELLED)} carry Vicon '*N' trajectory-fragment ids, not marker labels")
    if len(seeds) > 1:
        print(f"\n0a. over degrade seeds {', '.join(map(str, seeds))}: labeler accuracy worst / mean, closest-point "
              "mean, forced losses re-acquired within 1 s")
        for name, accs, bases, reacqs in summary:
            within = f"{np.sum(np.array(reacqs) <= 1.0)}/{len(reacqs)}" if reacqs else "-"
            print(f"{name:<36}{min(accs):>7.3f}{np.mean(accs):>7.3f}{np.mean(bases):>7.3f}{within:>8}")


def long_take_pipeline(mocap: Path) -> None:
    """label → fit-skeleton → BVH → build-graph through the CLIs on the full cmu_85_12 (37 s)."""
    from engine.graph.cli import build_graph_main
    from engine.labeling.cli import main as label_main
    from engine.skeleton_fit.cli import main as fit_main

    print("\n0b. full pipeline on the long CMU take cmu_85_12 (4 499 frames, 37 s) through the CLIs")
    with tempfile.TemporaryDirectory() as tmp:
        labelled, bvh, graph = Path(tmp) / "labelled.c3d", Path(tmp) / "skel.bvh", Path(tmp) / "graph.npz"
        start = time.perf_counter()
        steps = [("label --degrade 1", label_main, [str(mocap / "markers" / "cmu_85_12.c3d"), "-o", str(labelled),
                                                    "--degrade", "1"]),
                 ("fit-skeleton", fit_main, [str(labelled), "-o", str(bvh)]),
                 ("build-graph", build_graph_main, [str(bvh), "-o", str(graph)])]
        for name, command, argv in steps:
            print(f"--- courtside {name}")
            if command(argv) != 0:
                print(f"courtside {name} failed")
                return
        print(f"pipeline wall time {time.perf_counter() - start:.0f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mocap", type=Path, default=find_shared_mocap())
    parser.add_argument("--quick", action="store_true", help="fewer frames and subject counts")
    parser.add_argument("--only-takes", action="store_true", help="only table 0 and the long-take pipeline")
    parser.add_argument("--seeds", default="1", help="degrade seeds of table 0, comma-separated (default 1)")
    args = parser.parse_args()
    if args.mocap is None:
        sys.exit("the shared mocap set is needed (--mocap)")
    takes_table(args.mocap, tuple(int(x) for x in args.seeds.split(",")))
    long_take_pipeline(args.mocap)
    if args.only_takes:
        return

    data, subjects, together = tennis(args.mocap)
    rows = [(f"tennis 2x39 {rec}", run_case(together, subjects, data.fps, 150,
                                           LabelingConfig(train_frames=150, recovery=rec))) for rec in ("offsets", "kabsch")]
    _print("1. two-player tennis serve, 50 Hz, train 150 frames, players 0.6 m apart after training", rows)

    print("\n1b. recovery error / largest pair distance in the body (paper Fig. 8 metric), tennis, median (samples)")
    breakdowns = {}
    for rec in ("offsets", "kabsch"):
        stream, labeler, results, _ = label_stream(together, subjects, data.fps, 150,
                                                   LabelingConfig(train_frames=150, recovery=rec))
        breakdowns[rec] = recovery_breakdown(stream, labeler, results, 150)
    for key in breakdowns["offsets"]:
        cells = "".join(f"{breakdowns[rec].get(key, (np.nan, 0))[0]:>10.3f} ({breakdowns[rec].get(key, (0, 0))[1]:>4d})"
                        for rec in ("offsets", "kabsch"))
        print(f"{key:<22}{cells}   [offsets, kabsch]")

    a = read_c3d(args.mocap / "markers" / "cmu_135_02.c3d")
    b = read_c3d(args.mocap / "markers" / "cmu_85_12.c3d")
    frames = min(a.n_frames, b.n_frames, 1500 if args.quick else 3000)
    pos = np.concatenate([a.positions_m[:frames], b.positions_m[:frames]], axis=1)
    subj = np.repeat([0, 1], [a.positions_m.shape[1], b.positions_m.shape[1]])
    rows = []
    for step, fps in ((1, 120), (2, 60), (4, 30)):
        sub = pos[::step]
        train = 600 // step  # 5 s: the break dancer (85_12) stands still for the first ~2.5 s
        sub = bring_together(sub, subj, 1, 0.6, train, 50 // step)
        rows.append((f"cmu 2x41 @{fps} fps", run_case(sub, subj, a.fps / step, train,
                                                      LabelingConfig(train_frames=train, recovery="kabsch"))))
    _print("2. two CMU subjects (135_02 + 85_12, 25 s) brought to 0.6 m after 5 s training, downsampled "
           "(paper Exp. 1; kabsch recovery)", rows)

    rows = []
    counts = (2, 4) if args.quick else (2, 4, 6, 10)
    for n in counts:
        copies = n // 2
        grid = np.concatenate([together + np.array([1.2 * k, 2.5 * (k % 2), 0.0]) for k in range(copies)], axis=1)
        subj = np.concatenate([subjects + 2 * k for k in range(copies)])
        frames = 300 if args.quick else len(grid)
        row = run_case(grid[:frames], subj, data.fps, 150, LabelingConfig(train_frames=150, recovery="kabsch"),
                       baselines=(n == 2))
        rows.append((f"{n} subjects ({len(subj)} mk)", row))
    _print("3. scaling: tennis players replicated (frames/s per subject count; target >= 120 fps at 2 subjects)", rows)


if __name__ == "__main__":
    main()
