"""Which markers belong to which body segment, and the segment tree (the paper's "two-file process").

Why a table: paper 002 needs markers assigned to segments and a tree rooted at the pelvis; it never uses what a
marker means beyond that. The two shipped tables cover the Vicon Plug-in-Gait family used by the real data on
hand (Kinetics Toolkit tennis serve: ``LASI/RASI/LPSI/RPSI`` pelvis; CMU 41-marker set: ``LFWT/RFWT/LBWT/RBWT``).
Joint names follow the BVH naming the rest of Courtside uses (Hips, LeftUpLeg, ...).

Segment frames need, in order of preference: three markers (case 3); two markers plus the joint centre (case 2);
one marker plus the joint centre and a hinge axis (case 1). A hand with only a finger marker cannot be oriented,
so such markers are landmarks of their parent segment (points fixed in its frame), not segments.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Landmark:
    """A point fixed in a segment's frame at the mean of ``markers`` (e.g. the wrist between WRA and WRB).

    It becomes a BVH joint that turns with its segment (identity local rotation) so the skeleton carries the
    joints other parts expect (Chest, clavicle, wrist, toes), or an End Site when ``end`` is set. ``parent`` is
    another landmark of the same segment, or None for the segment's own joint."""

    name: str
    markers: tuple[str, ...]
    parent: str | None = None
    end: bool = False


@dataclass(frozen=True)
class SegmentSpec:
    """One body segment; ``name`` is its joint's name (the joint at its rotation centre with the parent).

    ``markers`` define its frame (the first three are used). ``attach`` is the BVH parent when it is a landmark
    of the parent segment rather than the parent's own joint (the arm hangs from the clavicle landmark)."""

    name: str
    parent: str | None
    markers: tuple[str, ...]
    attach: str | None = None
    landmarks: tuple[Landmark, ...] = ()


@dataclass(frozen=True)
class MarkerSet:
    """A segment tree in root-to-leaf order (every parent appears before its children)."""

    name: str
    segments: tuple[SegmentSpec, ...]

    def __post_init__(self) -> None:
        seen: set[str] = set()
        for seg in self.segments:
            if seg.parent is None and seen:
                raise ValueError(f"marker set {self.name}: only the first segment may be the root ({seg.name})")
            if seg.parent is not None and seg.parent not in seen:
                raise ValueError(f"marker set {self.name}: {seg.name}'s parent {seg.parent} must come before it")
            if not seg.markers:
                raise ValueError(f"marker set {self.name}: segment {seg.name} has no markers")
            seen.add(seg.name)
        if len(self.segments[0].markers) < 3:
            raise ValueError(f"marker set {self.name}: the root needs at least 3 markers (paper 002 case 3)")

    def marker_names(self) -> list[str]:
        """Every marker the set uses (frame markers and end sites)."""
        names = [m for seg in self.segments for m in seg.markers]
        names += [m for seg in self.segments for lm in seg.landmarks for m in lm.markers]
        return list(dict.fromkeys(names))


def _plug_in_gait(name: str, pelvis: tuple[str, ...], shank: str, foot: tuple[str, ...]) -> MarkerSet:
    """Shared Plug-in-Gait layout; the variants differ only in pelvis, shank and foot marker names.

    Joint names follow the Bandai-Namco BVH convention known to engine.mocap.joint_roles, so the fitted motion
    works with virtual sensors and the motion graph: Hips, Spine (lumbar joint, thorax segment), Chest, Neck
    (head segment), Head, Shoulder_L (clavicle landmark at the acromion marker), UpperArm_L, LowerArm_L,
    Hand_L (wrist landmark), Hand_L_end (finger), UpperLeg_L, LowerLeg_L, Foot_L, Toes_L."""

    def side(s: str) -> list[SegmentSpec]:
        return [
            SegmentSpec(f"UpperLeg_{s}", "Hips", (f"{s}THI", f"{s}KNE")),
            SegmentSpec(f"LowerLeg_{s}", f"UpperLeg_{s}", (f"{s}{shank}", f"{s}ANK")),
            SegmentSpec(f"Foot_{s}", f"LowerLeg_{s}", tuple(f"{s}{m}" for m in foot),
                        landmarks=(Landmark(f"Toes_{s}", (f"{s}TOE",)),)),
            SegmentSpec(f"UpperArm_{s}", "Spine", (f"{s}UPA", f"{s}ELB"), attach=f"Shoulder_{s}"),
            SegmentSpec(f"LowerArm_{s}", f"UpperArm_{s}", (f"{s}WRA", f"{s}WRB", f"{s}FRM"),
                        landmarks=(Landmark(f"Hand_{s}", (f"{s}WRA", f"{s}WRB")),
                                   Landmark(f"Hand_{s}_end", (f"{s}FIN",), f"Hand_{s}", True))),
        ]

    thorax = ("C7", "CLAV", "STRN", "T10")
    segments = [
        SegmentSpec("Hips", None, pelvis),
        SegmentSpec("Spine", "Hips", thorax, landmarks=(
            Landmark("Chest", thorax),
            Landmark("Shoulder_L", ("LSHO",), "Chest"),
            Landmark("Shoulder_R", ("RSHO",), "Chest"))),
        SegmentSpec("Neck", "Spine", ("LFHD", "RFHD", "LBHD", "RBHD"), attach="Chest",
                    landmarks=(Landmark("Head", ("LFHD", "RFHD", "LBHD", "RBHD")),)),
    ]
    return MarkerSet(name, tuple(segments + side("L") + side("R")))


PLUG_IN_GAIT = _plug_in_gait("plug-in-gait", ("LASI", "RASI", "LPSI", "RPSI"), "TIB", ("HEE", "TOE"))
CMU_41 = _plug_in_gait("cmu-41", ("LFWT", "RFWT", "LBWT", "RBWT"), "SHN", ("HEE", "TOE", "MT5"))
MARKER_SETS = {m.name: m for m in (PLUG_IN_GAIT, CMU_41)}


def detect_marker_set(labels: list[str]) -> MarkerSet:
    """The shipped marker set whose markers are all present in ``labels`` (subject prefixes ``Name:`` ignored)."""
    bare = {label.split(":")[-1] for label in labels}
    for marker_set in MARKER_SETS.values():
        if set(marker_set.marker_names()) <= bare:
            return marker_set
    raise ValueError(
        f"no known marker set matches these labels (known: {', '.join(MARKER_SETS)}); labels: {sorted(bare)[:12]}..."
    )
