"""Seed 004 (Mousas 2017, Table 2): HMM frame rate vs training-database size.

Databases are cut from Bandai Namco datasets 1 + 2 at 30 fps by behaviour, as in Table 2: walk only (500, 1000,
2000, 4000 frames), walk + run (5000), walk + run + dash + walk-back (10000; Bandai has no jumps or hops, so
dash and walking backwards stand in for J and H). A held-out walk (right-foot IMU, acc + gyro) is streamed
through HMMReconstructor; per-frame compute time is measured around push() (the paper's "latency" column also
buffers frames and is not comparable, spec B3). The ratio column is against the 500-frame model of this run.

Then (--tests-per-type, default 4) the Table 3 analogue: error per motion type on CMU subject 16 + 131.

    .venv/bin/python bench/bench_hmm.py [--shared /work/shared/mocap] [--frames 300] [--tests-per-type 4]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from engine.hmm.evaluation import reconstruct, train_model  # noqa: E402
from engine.hmm.features import imu_features  # noqa: E402
from engine.mocap import Motion, load_database, standard_placements  # noqa: E402

ROWS = [("W", 500), ("W", 1000), ("W", 2000), ("W", 4000), ("W-R", 5000), ("W-R-D-B", 10000)]
CONTENT = {"W": "walk", "R": "run", "D": "dash", "B": "walk-back"}


def take_frames(pools: dict[str, list[Motion]], kinds: str, total: int) -> tuple[list[Motion], list[str]]:
    """Whole clips of each behaviour until `total` frames, an equal share each; the scarce behaviours (listed
    last) go first and the plentiful walk/run clips make up any shortfall."""
    motions, labels, collected = [], [], 0
    order = kinds.split("-")[::-1]
    for i, kind in enumerate(order):
        need = (total - collected) // (len(order) - i)
        for m in pools[CONTENT[kind]]:
            if need <= 0:
                break
            part = m.slice(0, min(need, m.n_frames))
            motions.append(part)
            labels.append(CONTENT[kind])
            need -= part.n_frames
            collected += part.n_frames
    return motions, labels


def per_type_table(shared: Path, tests_per_type: int) -> None:
    """Table 3 analogue: error per motion type, per-type model (1 and 2 IMUs) vs one all-types model.

    CMU subject 16 (walk / run / jump, labelled from the root trajectory) with leave-one-out over
    `tests_per_type` clips of each type; hopping from CMU 131_03 (start-hop-stop, its own skeleton), split in
    two halves that are held out in turn (hop has no all-types entry: different skeleton)."""
    from engine.hmm.evaluation import behaviour_of, hmm_leave_one_out
    from engine.mocap import resample
    from engine.olng.metrics import summarise

    motions = load_database(sorted((shared / "cmu-amc" / "16").glob("*.amc")), fps=30.0)
    labels = [behaviour_of(resample(m, 30.0)) for m in motions]
    hop = load_database([shared / "cmu-bvh" / "131_03.bvh"], fps=30.0)[0]
    half = hop.n_frames // 2
    hops = [hop.slice(0, half), hop.slice(half)]
    print(f"\nper motion type (joint cm / RMS root-frame cm; clean IMUs, {tests_per_type} held-out clips per type)")
    print(f"{'type':<8}{'frames':>7}{'1 IMU':>16}{'2 IMUs':>16}{'all types, 1 IMU':>20}")
    totals = {"one": [], "two": [], "all": []}
    for kind in ("walk", "run", "jump", "hop"):
        if kind == "hop":
            pool, idx, lab = hops, [0, 1], ["hop", "hop"]
            tests, mixed = idx, None
        else:
            pool, lab = motions, labels
            idx = [i for i, b in enumerate(labels) if b == kind]
            tests = [idx[int(k)] for k in np.linspace(0, len(idx) - 1, min(tests_per_type, len(idx)))]
            mixed = hmm_leave_one_out(pool, tests, ("right_foot",), labels=lab)
        one = hmm_leave_one_out(pool, tests, ("right_foot",), labels=lab, train_indices=idx)
        two = hmm_leave_one_out(pool, tests, ("right_foot", "right_wrist"), labels=lab, train_indices=idx)
        fmt = lambda sc: f"{summarise(sc)['joint_cm']:6.2f} / {summarise(sc)['rms_root_cm']:5.2f}"  # noqa: E731
        frames = summarise(one)["frames"]
        print(f"{kind:<8}{frames:>7}{fmt(one):>16}{fmt(two):>16}{fmt(mixed) if mixed else '-':>20}")
        totals["one"] += one
        totals["two"] += two
        totals["all"] += mixed or []
    print(f"{'total':<8}{summarise(totals['one'])['frames']:>7}{fmt(totals['one']):>16}{fmt(totals['two']):>16}"
          f"{fmt(totals['all']):>20}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--shared", type=Path, default=Path(os.environ.get("COURTSIDE_MOCAP_DIR", "/work/shared/mocap")))
    ap.add_argument("--frames", type=int, default=300, help="frames of the held-out walk to stream")
    ap.add_argument("--tests-per-type", type=int, default=4, help="held-out clips per motion type (0 = skip table)")
    args = ap.parse_args(argv)
    pools: dict[str, list[Motion]] = {}
    for content in CONTENT.values():
        paths = sorted((args.shared / "bandai-namco-1" / "data").glob(f"dataset-1_{content}_*.bvh"))
        paths += sorted((args.shared / "bandai-namco-2" / "data").glob(f"dataset-2_{content}_*.bvh"))
        if not paths:
            print(f"no Bandai '{content}' clips under {args.shared}", file=sys.stderr)
            return 2
        pools[content] = load_database(paths, fps=30.0)
    test = pools["walk"].pop(0)                                  # held out from every database
    acc, gyro = imu_features(test, standard_placements(test.skeleton, ("right_foot",)))
    acc, gyro = acc[: args.frames], gyro[: args.frames]
    print(f"held-out walk {test.name}: {len(acc)} frames at 30 fps, IMU on the right foot")
    print(f"{'motions':<10}{'frames':>8}{'segments':>10}{'states':>8}{'train s':>9}{'ms/frame':>10}{'p95 ms':>8}{'fps':>8}{'ratio':>7}")
    base = None
    for kinds, total in ROWS:
        motions, labels = take_frames(pools, kinds, total)
        t0 = time.perf_counter()
        model = train_model(motions, ("right_foot",), labels)
        train_s = time.perf_counter() - t0
        _, _, frames = reconstruct(model, acc, gyro, test.skeleton.n_joints, test.root_positions_m[0], test.rotations[0, 0])
        ms = 1000 * np.array([f.compute_s for f in frames])
        fps = 1000 / ms.mean()
        base = base or fps
        segments = sum(p.seg_body.shape[0] for p in model.phases)
        print(f"{kinds:<10}{sum(m.n_frames for m in motions):>8}{segments:>10}{model.n_states:>8}{train_s:>9.1f}"
              f"{ms.mean():>10.2f}{np.percentile(ms, 95):>8.2f}{fps:>8.0f}{fps / base:>7.2f}")
    print("target: >= 60 fps at 10,000 frames (paper: 12 fps)")
    if args.tests_per_type:
        per_type_table(args.shared, args.tests_per_type)
    return 0


if __name__ == "__main__":
    sys.exit(main())
