"""Accuracy per athlete on chained held-out takes (issue 20: "equals the single-athlete figures, same table, two
columns").

    PYTHONPATH=$PWD nice -n 10 .venv/bin/python bench/bench_athletes_accuracy.py [--engine motion-graph] [--lag 0.5]
        [--mocap-dir ../shared/mocap --pattern 'bandai-namco-1/data/*.bvh' --take-seconds 30]

Two different chained takes of the shipped clips (held out of the engine's database) are worn by two athletes,
alice on station st1 and bob on st2 (a two-`[[athletes]]` court map, the gateway's hello built from it), each
with its own camera track. Both streams, interleaved as the console receives them, go through the console's
per-athlete path (`gui.athletes_replay.synthesize_athletes`: athlete -> station from the hello, one synthesis per
athlete, the bridge routing samples and each athlete's camera track). Beside each athlete's column: the same take
run alone, through the same console path with only that athlete, and offline through the recorded-take synthesis
(`engine.stream.synthesize_streams`). The engines share no state, so all three must be equal bit for bit; the
bench says whether they are and exits 1 if not.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from engine.evaluation.engines import on_take_grid
from engine.evaluation.metrics import frame_errors
from engine.evaluation.labels import clip_label
from engine.evaluation.takes import chain_clips, plan_chained_takes
from engine.mocap import load_clip, sample_clips
from engine.stream.databases import engine_spec
from engine.stream.registry import adapter
from engine.stream.session import synthesize_streams
from gateway.athletes import AthleteConfig, AthleteMap, SensorRef, athletes_info
from gui.athletes_replay import (SimulatedAthlete, athlete_stations, in_stream_order, simulate_athlete,
                                 synthesize_athletes)
from gui.engine_link import check_worn_sensors, synthesis_setup, worn_sensors

TAKES = {"alice": ("st1", ["16_05", "16_21"]), "bob": ("st2", ["16_11", "16_45"])}  # the demo's held-out clips
OFFSETS_S = {"alice": 1000.0, "bob": 1000.37}  # gateway time of each take's first frame (they need not align)
METRICS = (("global_cm", "global joint error (cm)"), ("root_relative_cm", "root-relative error (cm)"),
           ("position_cm", "root position error (cm)"), ("heading_deg", "heading error (deg)"))


def court(n_sensors: int) -> list[dict]:
    """The gateway's hello ``athletes`` of a two-athlete court config, and the station list it streams."""
    configs = [AthleteConfig(name, side, tuple(SensorRef.parse(f"{station}:{k}") for k in range(n_sensors)))
               for (name, (station, _)), side in zip(TAKES.items(), ("near", "far"))]
    return athletes_info(AthleteMap(configs))


def scores(poses, sim: SimulatedAthlete) -> dict[str, float]:
    """Mean errors of the poses against the take's truth (the poses' gateway times back on the take's frames)."""
    joints = on_take_grid(np.stack([p.joint_positions_m for p in poses]),
                          np.array([p.t_s for p in poses]) - sim.offset_s, sim.take)
    errors = frame_errors(joints, sim.take.joints_m, sim.take.skeleton)
    return {key: float(np.mean(getattr(errors, key))) for key, _ in METRICS}


def identical(a: list, b: list) -> bool:
    """Same frames, same joint positions to the last bit."""
    return len(a) == len(b) and all(p.frame == q.frame and np.array_equal(p.joint_positions_m, q.joint_positions_m)
                                    for p, q in zip(a, b))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--engine", default="motion-graph")
    p.add_argument("--lag", type=float, default=0.5, help="fixed lag of each athlete's live engine (s)")
    p.add_argument("--mocap-dir", type=Path, default=None,
                   help="a mocap corpus (e.g. ../shared/mocap) instead of the shipped clips: two chained takes of "
                        "--take-seconds planned from its labels, a graph built from the rest")
    p.add_argument("--pattern", default="bandai-namco-1/data/*.bvh", help="clip files under --mocap-dir")
    p.add_argument("--take-seconds", type=float, default=30.0)
    p.add_argument("--fps", type=float, default=30.0, help="--mocap-dir clips resampled to this rate")
    args = p.parse_args()
    if args.mocap_dir is None:
        clips = sample_clips()
        takes = {name: clips_ for name, (_, clips_) in TAKES.items()}
    else:
        clips = {path.stem: path for path in sorted(args.mocap_dir.glob(args.pattern))}
    names = list(clips)
    motions = [load_clip(clips[n], None if args.mocap_dir is None else args.fps) for n in names]
    if args.mocap_dir is not None:
        labels = [clip_label(clips[n]).content for n in names]
        plan = plan_chained_takes(labels, [m.n_frames / m.fps for m in motions], 2, args.take_seconds, 0, "walk")
        takes = {name: [names[i] for i in ids] for name, ids in zip(TAKES, plan)}
    held = [c for clips_ in takes.values() for c in clips_]
    if args.mocap_dir is None:
        spec, _ = engine_spec(args.engine, n_worn=6, exclude=held)
    else:
        train = [m for n, m in zip(names, motions) if n not in held]
        spec = adapter(args.engine).build_spec(train, f"{len(train)} clips of {args.mocap_dir / args.pattern}")
    stations = [{"station": st, "sensors": [{"sensor": k, "nominal_hz": 100.0} for k in range(len(spec.sensor_names))]}
                for st, _ in TAKES.values()]
    routing = athlete_stations(court(len(spec.sensor_names)), stations)
    setups, sims = {}, {}
    for seed, (name, station) in enumerate(routing.items()):
        keys, _ = worn_sensors(list(spec.sensor_names), station)
        check_worn_sensors(spec, keys, stations)
        setups[name] = synthesis_setup(spec, keys, args.lag)
        take = chain_clips(motions, [names.index(c) for c in takes[name]], names)
        sims[name] = simulate_athlete(name, station, take, spec.sensor_names, OFFSETS_S[name], seed)
    together = synthesize_athletes(setups, in_stream_order(*(s.messages for s in sims.values())))
    alone = {name: synthesize_athletes({name: setups[name]}, sims[name].messages)[name] for name in setups}
    offline = {name: synthesize_streams(lambda: spec.live(args.lag), sims[name].streams, setups[name].sensors,
                                        spec.rate_hz)[0] for name in setups}
    print(f"{spec.label}, lag {args.lag:g} s; database without {', '.join(held)}")
    for name, sim in sims.items():
        print(f"{name} ({sim.station}): {sim.take.duration_s:.1f} s of " + " > ".join(takes[name]))
    columns = {(name, mode): scores(poses[name], sims[name]) for name in setups
               for mode, poses in (("two athletes", together), ("alone", alone), ("offline", offline))}
    print(f"{'':28s}" + "".join(f"{f'{n}: {m}':>20s}" for n, m in columns))
    for key, label in METRICS:
        print(f"{label:28s}" + "".join(f"{c[key]:20.2f}" for c in columns.values()))
    same = {name: identical(together[name], alone[name]) and identical(together[name], offline[name])
            for name in setups}
    print("two athletes = alone = offline, bit for bit: "
          + ", ".join(f"{n} {'yes' if ok else 'NO'} ({len(together[n])} poses)" for n, ok in same.items()))
    return 0 if all(same.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
