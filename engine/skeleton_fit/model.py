"""Fit joint centres down a segment tree from labelled markers, then replay the skeleton frame by frame.

Procedure (paper 002 §2.3, §2.6): for each joint in root-to-leaf order, express the child's marker trajectories
in the parent segment's frame, fit them with ``fit_joint`` (ball → sphere centre, hinge → circle centre on the
axis), and store that centre ``v_j`` (and the axis ``n_j``) in parent-local coordinates. Playback needs no
iteration: ``c_jk = o_parent,k + R_parent,k v_j`` and the child's frame is rebuilt from its markers (+ ``c_jk``).

Units: whatever the marker positions use (Courtside reads C3D into metres); the thresholds in
``JointFitConfig`` are in that unit.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from engine import progress
from .frames import frame_from_axis, frame_from_three, to_local, to_world
from .gdke import DegenerateFitError, JointFit, JointFitConfig, JointType, fit_joint
from .markerset import MarkerSet, SegmentSpec


@dataclass(frozen=True)
class SkeletonFitConfig:
    """joint: thresholds of the ball/hinge/static decision. max_samples: subsample each joint's trajectory to at
    most this many valid frames (evenly spaced; None = all) — the paper uses ~100, more only costs O(N)."""

    joint: JointFitConfig = field(default_factory=JointFitConfig)
    max_samples: int | None = None


@dataclass(frozen=True)
class FittedJoint:
    """A segment's joint with its parent: centre in the parent frame, and how it was classified."""

    segment: str
    parent: str | None
    centre_local: np.ndarray  # (3,) v_j in the parent frame (root: zeros, the root frame origin)
    axis_local: np.ndarray | None  # (3,) hinge axis n_j in the parent frame
    fit: JointFit | None  # None for the root
    landmarks_local: dict[str, np.ndarray]  # landmark name -> (3,) mean marker position in this segment's frame


@dataclass
class SkeletonModel:
    """The fitted skeleton: one FittedJoint per segment, root first. Replays on any frames of the same markers."""

    marker_set: MarkerSet
    joints: list[FittedJoint]

    def segment_frames(self, markers: dict[str, np.ndarray]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per segment (origin (F,3), rot (F,3,3)) in world, built root to leaf exactly as during fitting."""
        return _build_frames(self.marker_set, markers, {j.segment: j for j in self.joints})

    def joint_positions(self, markers: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """World joint centres per segment (F,3): the root frame origin, then c_j = o_parent + R_parent v_j."""
        frames = self.segment_frames(markers)
        out: dict[str, np.ndarray] = {}
        for joint in self.joints:
            if joint.parent is None:
                out[joint.segment] = frames[joint.segment][0]
            else:
                out[joint.segment] = to_world(joint.centre_local, *frames[joint.parent])
        return out


def _segment_frame(
    seg: SegmentSpec,
    markers: dict[str, np.ndarray],
    centre: np.ndarray | None,
    axis_world: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Paper 002 cases 3 / 2 / 1 in that order of preference."""
    pts = [markers[m] for m in seg.markers[:3]]
    if len(pts) == 3:
        return frame_from_three(*pts)
    if centre is None:
        raise ValueError(f"segment {seg.name}: fewer than 3 markers and no joint centre to complete its frame")
    if len(pts) == 2:
        return frame_from_three(pts[0], pts[1], centre)
    if axis_world is None:
        raise ValueError(f"segment {seg.name}: one marker and a ball joint cannot define a frame; make it an end site")
    return frame_from_axis(pts[0], centre, axis_world)


def _build_frames(
    marker_set: MarkerSet, markers: dict[str, np.ndarray], joints: dict[str, FittedJoint]
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    frames: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for seg in marker_set.segments:
        joint = joints[seg.name]
        if seg.parent is None:
            frames[seg.name] = _segment_frame(seg, markers, None, None)
            continue
        origin, rot = frames[seg.parent]
        centre = to_world(joint.centre_local, origin, rot)
        axis = None if joint.axis_local is None else np.einsum("fij,j->fi", rot, joint.axis_local)
        frames[seg.name] = _segment_frame(seg, markers, centre, axis)
    return frames


def _subsample(points: np.ndarray, max_samples: int | None) -> np.ndarray:
    valid = points[~np.isnan(points).any(axis=1)]
    if max_samples is None or len(valid) <= max_samples:
        return valid
    return valid[np.linspace(0, len(valid) - 1, max_samples).round().astype(int)]


def fit_skeleton(
    markers: dict[str, np.ndarray], marker_set: MarkerSet, config: SkeletonFitConfig = SkeletonFitConfig()
) -> SkeletonModel:
    """Fit every joint of ``marker_set`` from labelled marker trajectories ``{name: (F,3)}`` (NaN = missing).

    A joint whose child markers do not move relative to the parent (STATIC) is placed at the child's marker
    centroid, since any point is a valid rotation centre for a rigidly attached segment."""
    missing = [m for m in marker_set.marker_names() if m not in markers]
    if missing:
        raise ValueError(f"marker set {marker_set.name}: markers missing from the data: {missing}")
    joints: dict[str, FittedJoint] = {}
    frames: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for seg in progress.bar(marker_set.segments, desc="fitting joints", unit="joint"):
        if seg.parent is None:
            frames[seg.name] = _segment_frame(seg, markers, None, None)
            joint = FittedJoint(seg.name, None, np.zeros(3), None, None, {})
        else:
            origin, rot = frames[seg.parent]
            local = [_subsample(to_local(markers[m], origin, rot), config.max_samples) for m in seg.markers]
            try:
                fit = fit_joint(local, config.joint)
            except DegenerateFitError as exc:
                raise DegenerateFitError(f"joint {seg.parent}->{seg.name}: {exc}") from exc
            centre = fit.centre if fit.kind is not JointType.STATIC else np.mean([p.mean(axis=0) for p in local], 0)
            joint = FittedJoint(seg.name, seg.parent, centre, fit.axis, fit, {})
            centre_world = to_world(centre, origin, rot)
            axis_world = None if fit.axis is None else np.einsum("fij,j->fi", rot, fit.axis)
            frames[seg.name] = _segment_frame(seg, markers, centre_world, axis_world)
        for landmark in seg.landmarks:
            point = np.mean([markers[m] for m in landmark.markers], axis=0)
            joint.landmarks_local[landmark.name] = np.nanmean(to_local(point, *frames[seg.name]), axis=0)
        joints[seg.name] = joint
    return SkeletonModel(marker_set, [joints[s.name] for s in marker_set.segments])
