"""`courtside label in.c3d -o labelled.c3d`: online labeling of every frame after the labelled training frames.

The input's first --train-frames frames (default: the first 10 s) must carry correct labels ("Subject:MARKER"),
or with --bootstrap only the first frame, the rest of the training window being labelled by closest point
(the paper's set-up: one labelled frame, subjects apart during training). Every later frame is taken as an unordered point cloud — the
labels in the file are ignored — and labelled online. --degrade SEED first scrambles the frames the way
optical capture does (shuffle, noise, gaps ≤ 20 frames, ghosts), removes one rigid body for 0.5 s every 10 s,
and scores the result against the file's own labels: accuracy per 10 s, re-acquisition time after each forced
loss, and the closest-point baseline on the same stream (engine.labeling.evaluation).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from engine import progress
from engine.atomic_write import refuse_overwriting_inputs
from engine.errors import ArgumentParser, CourtsideError, MalformedFileError, check_output_dir, cli_command
from engine.progress import add_quiet_argument
from engine.mocap import MarkerData, read_c3d

from .baseline import bootstrap_training_labels
from .c3d_io import write_c3d
from .config import LabelingConfig
from .labeler import LOST, RECOVERED, OnlineLabeler
from .evaluation import default_train_frames, evaluate_take
from .scenario import DegradeConfig, Stream, degrade


def subjects_of(labels: tuple[str, ...]) -> np.ndarray:
    """Subject id per label from the "Subject:" prefix (one subject if there is none)."""
    prefixes = [lab.split(":")[0] if ":" in lab else "" for lab in labels]
    names = sorted(set(prefixes), key=prefixes.index)
    return np.array([names.index(p) for p in prefixes])


def run(
    data: MarkerData, config: LabelingConfig, stream: Stream, bootstrap: bool = False
) -> tuple[np.ndarray, OnlineLabeler, list]:
    """Train on the first frames and label the rest of ``stream``. Returns (positions (F,L,3), labeler, results).

    bootstrap: trust only frame 0's labels and label the other training frames of ``stream`` by closest point."""
    t0 = config.train_frames
    training = data.positions_m[:t0]
    if bootstrap:
        training = bootstrap_training_labels(training[0], stream.clouds[1:t0])
    labeler = OnlineLabeler(config)
    labeler.train(training, subjects_of(data.labels), data.fps)
    out = np.full_like(data.positions_m, np.nan)
    out[:t0] = training
    results = []
    for t in progress.bar(range(t0, len(stream.clouds)), desc="labelling", unit="frame"):
        result = labeler.step(stream.clouds[t])
        out[t] = np.where((result.status == LOST)[:, None], np.nan, result.positions_m)
        results.append(result)
    return out, labeler, results


@cli_command("courtside label")
def main(argv: list[str]) -> int:
    parser = ArgumentParser(prog="courtside label", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("input", help="C3D whose first --train-frames frames are labelled")
    parser.add_argument("-o", "--output", required=True, help="labelled C3D to write (observed + recovered)")
    parser.add_argument("--train-frames", type=int, default=None,
                        help="labelled training frames (default: the first --train-s seconds)")
    parser.add_argument("--train-s", type=float, default=10.0,
                        help="training window in seconds when --train-frames is not given (at most half the take): "
                             "the clustering needs the body segments to move relative to each other")
    parser.add_argument("--recovery", choices=["offsets", "kabsch"], default=LabelingConfig.recovery,
                        help="a missing marker from its body's last complete shape fitted rigidly (kabsch) or from "
                             "one observed marker plus its last offset (offsets)")
    parser.add_argument("--degrade", type=int, metavar="SEED", help="scramble the input, then score the labels")
    parser.add_argument("--bootstrap", action="store_true",
                        help="trust only the first frame's labels; label the other training frames by closest point")
    add_quiet_argument(parser)
    args = parser.parse_args(argv)
    refuse_overwriting_inputs([args.output], [args.input])
    check_output_dir(args.output)
    try:
        data = read_c3d(args.input)
        train = args.train_frames or default_train_frames(data.n_frames, data.fps, args.train_s)
        config = LabelingConfig(train_frames=train, recovery=args.recovery)
        if data.n_frames <= config.train_frames:
            raise MalformedFileError(args.input, None, f"{data.n_frames} frames, not more than --train-frames "
                                                       f"{config.train_frames}")
        subjects = subjects_of(data.labels)
        start = time.perf_counter()
        if args.degrade is not None:
            evaluation, out, results = evaluate_take(data, subjects, config, args.degrade, args.bootstrap)
        else:
            stream = degrade(data.positions_m, subjects, DegradeConfig(0.0, 0.0, 1, 0.0, 0.0), np.random.default_rng(0))
            out, _, results = run(data, config, stream, args.bootstrap)
        elapsed = time.perf_counter() - start
        write_c3d(args.output, MarkerData(data.labels, out, data.fps, data.name))
    except ValueError as exc:  # the labeler refuses the file's markers (an argument error names itself)
        if isinstance(exc, CourtsideError):
            raise
        raise MalformedFileError(args.input, None, str(exc)) from None
    status = np.array([r.status for r in results])
    n = len(results)
    untrained = int(np.sum(np.isnan(out[: config.train_frames]).any(axis=2).all(axis=0)))
    # with --degrade the wall time also covers degrading, the closest-point baseline and scoring: the labeler's
    # own rate is the CPU frames/s printed with the accuracy
    rate = (f"in {elapsed:.1f} s wall with the baseline and scoring" if args.degrade is not None
            else f"at {n / elapsed:.0f} frames/s")
    print(f"{args.input}: {len(data.labels)} labels, {len(set(subjects))} subjects, trained on {config.train_frames} "
          f"frames ({config.train_frames / data.fps:.1f} s); labelled {n} frames {rate}")
    if untrained:
        print(f"{untrained} labels never seen in the training frames: they cannot be learned and stay unlabelled")
    print(f"observed {np.mean(status == 0):.3f}, recovered {np.mean(status == RECOVERED):.3f}, "
          f"lost {np.mean(status == LOST):.3f}; "
          f"mean gated candidates {np.mean([r.mean_candidates for r in results]):.2f}")
    if args.degrade is not None:
        ev = evaluation
        print(f"rigid bodies: sizes {ev.body_sizes}")
        print(f"accuracy {ev.score.accuracy:.3f} (closest-point baseline {ev.baseline.accuracy:.3f}); swaps between "
              f"subjects {ev.score.swaps} (baseline {ev.baseline.swaps}); recovered-marker error "
              f"{ev.recovered_error_mm:.1f} mm median; {ev.frames_per_s:.0f} frames/s CPU")
        print("accuracy per 10 s:   " + " ".join(f"{a:.3f}" for a in ev.window_accuracy))
        print("baseline per 10 s:   " + " ".join(f"{a:.3f}" for a in ev.baseline_window_accuracy))
        if ev.reacquire_s:
            print("re-acquisition after a forced 0.5 s loss of one rigid body (s): "
                  + " ".join("never" if np.isinf(r) else f"{r:.2f}" for r in ev.reacquire_s))
    print(f"wrote {args.output}")
    return 0
