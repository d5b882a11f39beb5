"""Command line: inspect a clip or convert it to BVH.

    python -m engine.mocap info CLIP [--fps 30]        frames, rate, height, speed, foot-contact duty, heading
    python -m engine.mocap convert CLIP OUT.bvh [--fps 30] [--order ZYX]
    python -m engine.mocap samples                     list the clips shipped in engine/data

CLIP is a .bvh, or an .amc with its .asf beside it. Bad files exit with status 2 and one line: the
MalformedFileError message (file, line, problem). A valid clip whose joint names match no known convention is
still summarised; only the role-based lines (foot contacts, heading) say why they are missing."""
from __future__ import annotations

import argparse
import sys

import numpy as np

from engine.errors import ArgumentParser, report_errors
from engine.mocap.bvh import write_bvh
from engine.mocap.clips import load_clip, sample_clips
from engine.mocap.ground import foot_contacts, root_heading
from engine.mocap.roles import UnknownSkeletonError
from engine.mocap.skeleton import forward_kinematics


def _info(args: argparse.Namespace) -> None:
    motion = load_clip(args.clip, fps=args.fps)
    pos, _ = forward_kinematics(motion)
    height = np.max(pos[..., 1].max(axis=1) - pos[..., 1].min(axis=1))
    step = np.linalg.norm(np.diff(motion.root_positions_m[:, [0, 2]], axis=0), axis=1).sum()
    print(f"{motion.name}: {motion.n_frames} frames at {motion.fps:g} Hz ({motion.duration_s:.2f} s), "
          f"{motion.skeleton.n_joints} joints")
    print(f"  height {height:.2f} m, ground path {step:.2f} m ({step / motion.duration_s:.2f} m/s)")
    try:
        contacts = foot_contacts(motion, positions_m=pos)
        heading = np.degrees(root_heading(motion, positions_m=pos))
    except UnknownSkeletonError as exc:  # feet and hips are found by joint name
        print(f"  foot contacts and heading: n/a ({exc})")
        return
    print(f"  foot contact duty left {contacts[:, 0].mean():.2f} right {contacts[:, 1].mean():.2f}, "
          f"both feet off {(~contacts.any(axis=1)).mean():.2f}")
    print(f"  heading first {heading[0]:.0f} deg, last {heading[-1]:.0f} deg")


def _convert(args: argparse.Namespace) -> None:
    motion = load_clip(args.clip, fps=args.fps)
    write_bvh(args.out, motion, order=args.order)
    print(f"wrote {args.out}: {motion.n_frames} frames at {motion.fps:g} Hz")


def _main(argv: list[str]) -> int:
    parser = ArgumentParser(prog="python -m engine.mocap", description="Inspect or convert mocap clips.")
    sub = parser.add_subparsers(dest="command", required=True)
    info = sub.add_parser("info", help="summary of a clip")
    info.add_argument("clip")
    info.add_argument("--fps", type=float, default=None, help="resample first (Hz)")
    conv = sub.add_parser("convert", help="write a clip as BVH (centimetres)")
    conv.add_argument("clip")
    conv.add_argument("out")
    conv.add_argument("--fps", type=float, default=None, help="resample first (Hz)")
    conv.add_argument("--order", default="ZYX", help="Euler order of the BVH rotation channels")
    sub.add_parser("samples", help="list the shipped clips")
    args = parser.parse_args(argv)
    if args.command == "info":
        _info(args)
    elif args.command == "convert":
        _convert(args)
    else:
        for name, path in sample_clips().items():
            print(f"{name:8s} {path}")
    return 0


def main(argv: list[str] | None = None) -> int:
    return report_errors("python -m engine.mocap", _main, list(sys.argv[1:] if argv is None else argv))


if __name__ == "__main__":
    sys.exit(main())
