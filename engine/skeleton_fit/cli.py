"""`courtside fit-skeleton labelled.c3d -o skel.bvh`: joint centres, then the clip as a BVH motion.

Each joint centre starts from the GDKE closed form and is refined by a few Levenberg-Marquardt steps on the
geometric residual, which removes the closed form's bias on partial arcs (--refine-iterations 0 = GDKE only).
Per joint it reports the type (ball / hinge / static), the arc the child markers swept about the centre and the
expected centre error (from the fit's residuals and geometry: short arcs give large errors)."""
from __future__ import annotations


import numpy as np

from engine.atomic_write import refuse_overwriting_inputs
from engine.errors import ArgumentParser, MalformedFileError, check_output_dir, cli_command
from engine.progress import add_quiet_argument
from engine.mocap import read_c3d, write_bvh

from .gdke import DegenerateFitError, JointFitConfig
from .markerset import MARKER_SETS, detect_marker_set
from .model import SkeletonFitConfig, fit_skeleton
from .motion import to_motion


def subject_markers(labels: tuple[str, ...], positions_m: np.ndarray, subject: str | None) -> dict[str, np.ndarray]:
    """{bare marker name: (F,3)} of one subject (labels "Subject:MARKER"; default: the first subject)."""
    prefixes = [lab.split(":")[0] if ":" in lab else "" for lab in labels]
    chosen = subject if subject is not None else prefixes[0]
    if chosen not in prefixes:
        raise ValueError(f"subject {chosen!r} not in the file (subjects: {sorted(set(prefixes))})")
    return {lab.split(":")[-1]: positions_m[:, i] for i, lab in enumerate(labels) if prefixes[i] == chosen}


@cli_command("courtside fit-skeleton")
def main(argv: list[str]) -> int:
    parser = ArgumentParser(prog="courtside fit-skeleton", description=__doc__)
    parser.add_argument("input", help="labelled marker C3D")
    parser.add_argument("-o", "--output", required=True, help="BVH file to write")
    parser.add_argument("--subject", help="subject prefix (labels 'Subject:MARKER'); default: the first")
    parser.add_argument("--marker-set", choices=["auto", *MARKER_SETS], default="auto",
                        help="the capture's marker set (auto: the shipped set whose markers the file has)")
    parser.add_argument("--kappa-max", type=float, default=JointFitConfig.kappa_max, help="hinge if κ(C) above")
    parser.add_argument("--static-std-m", type=float, default=JointFitConfig.static_std, help="static if below")
    parser.add_argument("--max-samples", type=int, default=None, help="frames per joint fit (default: all)")
    parser.add_argument("--refine-iterations", type=int, default=JointFitConfig.refine_iterations,
                        help="geometric refinement steps after the closed form (0 = GDKE only)")
    add_quiet_argument(parser)
    args = parser.parse_args(argv)
    refuse_overwriting_inputs([args.output], [args.input])
    check_output_dir(args.output)
    try:
        data = read_c3d(args.input)
        markers = subject_markers(data.labels, data.positions_m, args.subject)
        marker_set = detect_marker_set(list(markers)) if args.marker_set == "auto" else MARKER_SETS[args.marker_set]
        config = SkeletonFitConfig(JointFitConfig(kappa_max=args.kappa_max, static_std=args.static_std_m,
                                                  refine_iterations=max(args.refine_iterations, 0)),
                                   args.max_samples)
        model = fit_skeleton(markers, marker_set, config)
        motion = to_motion(model, markers, data.fps, name=data.name)
        write_bvh(args.output, motion)
    except (DegenerateFitError, ValueError) as exc:  # the markers cannot give a skeleton: name the file
        if isinstance(exc, MalformedFileError):
            raise
        raise MalformedFileError(args.input, None, str(exc)) from None
    print(f"{args.input}: marker set {marker_set.name}, {motion.rotations.shape[0]} frames at {data.fps:g} Hz")
    print(f"{'joint':<14}{'parent':<14}{'type':<8}{'kappa':>9}{'radius_m':>10}{'arc_deg':>9}{'expected_mm':>12}"
          "  centre_in_parent_m")
    for joint in model.joints[1:]:
        fit = joint.fit
        print(f"{joint.segment:<14}{joint.parent:<14}{fit.kind.value:<8}{fit.kappa:>9.1f}{fit.radius:>10.3f}"
              f"{fit.arc_deg:>9.1f}{1000 * fit.expected_error:>12.1f}  "
              f"{np.array2string(joint.centre_local, precision=3)}")
    print(f"wrote {args.output} ({motion.skeleton.n_joints} joints)")
    return 0
