"""Motion-graph construction speed: mocap frames per second (seed 000 reports 51 Vicon frames/s).

    .venv/bin/python bench/bench_graph_build.py [--mocap-dir /work/shared/mocap] [--pattern GLOB] [--max-clips N]

Without --mocap-dir it uses the CMU sample shipped in engine/data. Loading/parsing (cached by engine.mocap) is
timed apart from the graph build; the build is split into per-clip features (FK, contacts, virtual sensors incl.
MSV streams) and graph assembly (transitions, MSV, interpolation) for each variant.
"""
from __future__ import annotations

import argparse
import glob
import time
from pathlib import Path

from engine.graph.cli import clip_label
from engine.graph.config import GraphConfig
from engine.graph.graph import build_from_clips
from engine.graph.mocap_adapter import clips_from_motions, mocap_sensor_model
from engine.mocap import SEED000_SENSORS, load_database, sample_clips, standard_placements


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--mocap-dir")
    p.add_argument("--pattern", default="bandai-namco-1/data/*.bvh")
    p.add_argument("--max-clips", type=int, default=0)
    p.add_argument("--variants", default="plain,msv,interp,msv+interp")
    args = p.parse_args()
    if args.mocap_dir:
        paths = [Path(x) for x in sorted(glob.glob(str(Path(args.mocap_dir) / args.pattern)))]
    else:
        paths = [x for n, x in sample_clips().items() if n.startswith("16_")]
    if args.max_clips:
        paths = paths[: args.max_clips]
    t0 = time.perf_counter()
    motions = load_database(paths, fps=30.0)
    t_load = time.perf_counter() - t0
    frames = sum(m.n_frames for m in motions)
    placements = standard_placements(motions[0].skeleton, SEED000_SENSORS)
    print(f"{len(paths)} clips, {frames} frames at 30 Hz; load+parse {t_load:.1f} s (cached after the first run)")
    print(f"{'variant':12s} {'features s':>10s} {'graph s':>8s} {'frames/s':>9s} {'nodes':>8s} {'edges':>8s}")
    for v in args.variants.split(","):
        cfg = GraphConfig(msv="msv" in v, interp="interp" in v)
        t1 = time.perf_counter()
        clips = clips_from_motions(motions, placements, cfg, [clip_label(x) for x in paths])
        t2 = time.perf_counter()
        g = build_from_clips(clips, cfg, mocap_sensor_model(motions[0].skeleton, placements, cfg.fps))
        t3 = time.perf_counter()
        print(f"{v:12s} {t2 - t1:10.1f} {t3 - t2:8.1f} {frames / (t3 - t1):9.0f} {g.n_nodes:8d} {g.n_edges:8d}")


if __name__ == "__main__":
    main()
