"""`courtside label in.c3d -o labelled.c3d`: online labeling of every frame after the labelled training frames.

The input's first --train-frames frames must carry correct labels ("Subject:MARKER"), or with --bootstrap
only the first frame, the rest of the training window being labelled by closest point (the paper's set-up:
one labelled frame, subjects apart during training). Every later frame is taken as an unordered point cloud — the
labels in the file are ignored — and labelled online. --degrade SEED first scrambles the frames the way
optical capture does (shuffle, noise, gaps ≤ 20 frames, ghosts) and then scores the result against the
file's own labels, next to the closest-point baseline.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from engine.errors import CourtsideError, MalformedFileError, check_output_dir, cli_command
from engine.mocap import MarkerData, read_c3d

from .baseline import ClosestPointTracker, bootstrap_training_labels
from .c3d_io import write_c3d
from .config import LabelingConfig
from .labeler import LOST, RECOVERED, OnlineLabeler
from .scenario import DegradeConfig, Score, Stream, degrade, score_frame


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
    for t in range(t0, len(stream.clouds)):
        result = labeler.step(stream.clouds[t])
        out[t] = np.where((result.status == LOST)[:, None], np.nan, result.positions_m)
        results.append(result)
    return out, labeler, results


@cli_command("courtside label")
def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="courtside label", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("input", help="C3D whose first --train-frames frames are labelled")
    parser.add_argument("-o", "--output", required=True, help="labelled C3D to write (observed + recovered)")
    parser.add_argument("--train-frames", type=int, default=LabelingConfig.train_frames)
    parser.add_argument("--recovery", choices=["offsets", "kabsch"], default=LabelingConfig.recovery)
    parser.add_argument("--degrade", type=int, metavar="SEED", help="scramble the input, then score the labels")
    parser.add_argument("--bootstrap", action="store_true",
                        help="trust only the first frame's labels; label the other training frames by closest point")
    args = parser.parse_args(argv)
    check_output_dir(args.output)
    try:
        data = read_c3d(args.input)
        config = LabelingConfig(train_frames=args.train_frames, recovery=args.recovery)
        if data.n_frames <= config.train_frames:
            raise MalformedFileError(args.input, None, f"{data.n_frames} frames, not more than --train-frames "
                                                       f"{config.train_frames}")
        subjects = subjects_of(data.labels)
        if args.degrade is not None:
            stream = degrade(data.positions_m, subjects, DegradeConfig(protect_frames=config.train_frames),
                             np.random.default_rng(args.degrade))
        else:
            stream = degrade(data.positions_m, subjects, DegradeConfig(0.0, 0.0, 1, 0.0, 0.0), np.random.default_rng(0))
        start = time.perf_counter()
        out, labeler, results = run(data, config, stream, args.bootstrap)
        elapsed = time.perf_counter() - start
        write_c3d(args.output, MarkerData(data.labels, out, data.fps, data.name))
    except ValueError as exc:  # the labeler refuses the file's markers (an argument error names itself)
        if isinstance(exc, CourtsideError):
            raise
        raise MalformedFileError(args.input, None, str(exc)) from None
    status = np.array([r.status for r in results])
    n = len(results)
    print(f"{args.input}: {len(data.labels)} labels, {len(set(subjects))} subjects, {len(labeler.bodies)} rigid bodies "
          f"(sizes {sorted(len(b) for b in labeler.bodies)}); labelled {n} frames at {n / elapsed:.0f} frames/s")
    print(f"observed {np.mean(status == 0):.3f}, recovered {np.mean(status == RECOVERED):.3f}, "
          f"lost {np.mean(status == LOST):.3f}; mean gated candidates {np.mean([r.mean_candidates for r in results]):.2f}")
    if args.degrade is not None:
        ours, base = Score(), Score()
        tracker = ClosestPointTracker(data.positions_m[config.train_frames - 1])
        for i, t in enumerate(range(config.train_frames, data.n_frames)):
            score_frame(ours, stream, t, results[i].label_point,
                        np.where((results[i].status == RECOVERED)[:, None], results[i].positions_m, np.nan))
            score_frame(base, stream, t, tracker.step(stream.clouds[t]))
        print(f"accuracy {ours.accuracy:.3f} (closest-point baseline {base.accuracy:.3f}); swaps between subjects "
              f"{ours.swaps} (baseline {base.swaps}); recovered-marker error "
              f"{1000 * np.median(ours.recovery_err_m) if ours.recovery_err_m else float('nan'):.1f} mm median")
    print(f"wrote {args.output}")
    return 0
