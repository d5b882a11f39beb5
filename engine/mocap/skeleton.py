"""Skeleton and Motion: the one in-memory representation every reader produces and every consumer uses.

Conventions (docs/CONTRACTS.md): world Y up, metres, quaternions (w, x, y, z). A joint's local rotation maps
its own frame to its parent's; its offset is its position in the parent's frame at rest. With all rotations
at identity every joint frame is aligned with the world (true for both BVH and ASF after conversion), so a
direction "up" or "forward" at rest means the same thing in every joint frame. Joints are stored in
topological order (parent index < child index) so forward kinematics is a single pass over joints with the
frame axis vectorised. BVH "End Site"s and ASF bone tips are kept as joints flagged `end_site`: they carry
no rotation but give the positions of toe tips, finger tips and the top of the head."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from engine.mocap import quaternions as quat


@dataclass(frozen=True, eq=False)
class Skeleton:
    """Joint hierarchy. `parents[0] == -1` (the root); `offsets_m[j]` is joint j in its parent's frame."""

    names: tuple[str, ...]
    parents: np.ndarray  # (J,) int, -1 for the root, parents[j] < j
    offsets_m: np.ndarray  # (J, 3) metres
    end_site: np.ndarray = field(default=None)  # (J,) bool: leaf with no rotation channels

    def __post_init__(self) -> None:
        parents = np.asarray(self.parents, dtype=int)
        offsets = np.asarray(self.offsets_m, dtype=float)
        end = np.zeros(len(parents), bool) if self.end_site is None else np.asarray(self.end_site, bool)
        if parents.ndim != 1 or offsets.shape != (len(parents), 3) or end.shape != parents.shape:
            raise ValueError("Skeleton: parents (J,), offsets_m (J,3) and end_site (J,) must agree")
        if len(self.names) != len(parents):
            raise ValueError("Skeleton: one name per joint")
        if len(parents) == 0 or parents[0] != -1 or np.any(parents[1:] < 0) or np.any(parents[1:] >= np.arange(1, len(parents))):
            raise ValueError("Skeleton: joints must be topologically ordered with a single root at index 0")
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "offsets_m", offsets)
        object.__setattr__(self, "end_site", end)

    @property
    def n_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Joint index by exact name (KeyError naming the joint if absent)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no joint named {name!r} in skeleton") from None

    def children(self, joint: int) -> list[int]:
        return [int(c) for c in np.flatnonzero(self.parents == joint)]

    def rest_positions(self) -> np.ndarray:
        """(J, 3) world positions of the zero-rotation pose with the root at the origin."""
        pos = np.zeros((self.n_joints, 3))
        for j in range(1, self.n_joints):
            pos[j] = pos[self.parents[j]] + self.offsets_m[j]
        return pos

    def scaled(self, factor: float) -> "Skeleton":
        """Same topology with every offset multiplied by `factor` (unit conversion)."""
        return Skeleton(self.names, self.parents, self.offsets_m * factor, self.end_site)

    def same_topology(self, other: "Skeleton") -> bool:
        return self.names == other.names and np.array_equal(self.parents, other.parents)


@dataclass(eq=False)
class Motion:
    """A clip: `root_positions_m` (F, 3) world position of joint 0, `rotations` (F, J, 4) local quaternions."""

    skeleton: Skeleton
    fps: float
    root_positions_m: np.ndarray
    rotations: np.ndarray
    name: str = ""

    def __post_init__(self) -> None:
        self.root_positions_m = np.asarray(self.root_positions_m, float)
        self.rotations = np.asarray(self.rotations, float)
        f = self.root_positions_m.shape[0]
        if self.root_positions_m.shape != (f, 3) or self.rotations.shape != (f, self.skeleton.n_joints, 4):
            raise ValueError(
                f"Motion {self.name!r}: root_positions_m {self.root_positions_m.shape} and rotations "
                f"{self.rotations.shape} do not match {self.skeleton.n_joints} joints")
        if not self.fps > 0:
            raise ValueError(f"Motion {self.name!r}: fps must be positive, got {self.fps}")

    @property
    def n_frames(self) -> int:
        return self.root_positions_m.shape[0]

    @property
    def duration_s(self) -> float:
        return self.n_frames / self.fps

    def slice(self, start: int, stop: int | None = None) -> "Motion":
        """Frames [start, stop) as a new Motion (copies, so edits do not leak back)."""
        return Motion(self.skeleton, self.fps, self.root_positions_m[start:stop].copy(),
                      self.rotations[start:stop].copy(), self.name)


def forward_kinematics(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """World joint positions (F, J, 3) in metres and world rotations (F, J, 3, 3) for every frame at once.

    Loops over joints only (topological order); each step is a batched matmul over all frames."""
    skel = motion.skeleton
    local = quat.to_matrix(motion.rotations)  # (F, J, 3, 3)
    n_frames, n_joints = local.shape[:2]
    glob = np.empty_like(local)
    pos = np.empty((n_frames, n_joints, 3))
    glob[:, 0] = local[:, 0]
    pos[:, 0] = motion.root_positions_m
    for j in range(1, n_joints):
        p = skel.parents[j]
        glob[:, j] = glob[:, p] @ local[:, j]
        pos[:, j] = pos[:, p] + glob[:, p] @ skel.offsets_m[j]
    return pos, glob


def pose_joint_positions(skeleton: Skeleton, root_m: np.ndarray, local_rotations: np.ndarray) -> np.ndarray:
    """(..., J, 3) world joint positions m of poses given as root positions (..., 3) m and local rotations
    (..., J, 4): `forward_kinematics` for any leading shape (one pose, a run of poses, a blend's columns)."""
    root = np.asarray(root_m, float)
    rots = np.asarray(local_rotations, float)
    lead = rots.shape[:-2]
    flat = Motion(skeleton, 1.0, root.reshape(-1, 3), rots.reshape(-1, *rots.shape[-2:]))
    return forward_kinematics(flat)[0].reshape(*lead, -1, 3)
