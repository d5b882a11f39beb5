"""The decided-pose known answer shared by the engines' tests (issue 29): `courtside synthesize --engine NAME -o
out.bvh --save-poses poses.npz` writes one pose twice, so the BVH read back gives the saved joints."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.mocap import forward_kinematics, read_bvh
from gateway.cli import main as courtside

MM = 1e-3


def bvh_joints(path: Path) -> np.ndarray:
    """(T, J, 3) world joints m of a BVH file (its forward kinematics)."""
    return forward_kinematics(read_bvh(path))[0]


def assert_synthesize_writes_the_saved_poses(engine: str, take: Path, folder: Path, lag: str | None,
                                             min_frames: int) -> None:
    """``synthesize --engine`` on ``take`` (with ``--lag`` when given): the saved poses carry rotations, at least
    ``min_frames`` of them, and the BVH's forward kinematics equals their joints within 1 mm, frame for frame."""
    from engine.stream.poses_file import load_poses

    out, saved = folder / f"{engine}.bvh", folder / "poses.npz"
    assert courtside(["synthesize", "--engine", engine, "--input", str(take), "-o", str(out), "--save-poses",
                      str(saved), "--quiet", *(["--lag", lag] if lag else [])]) == 0
    poses = load_poses(saved)
    assert poses.local_rotations is not None and len(poses.frame) > min_frames
    joints = bvh_joints(out)
    assert joints.shape == poses.joint_positions_m.shape
    assert np.abs(joints - poses.joint_positions_m).max() < MM
