"""Which markers belong to which body segment, and the segment tree (the paper's "two-file process").

Why a table: paper 002 needs markers assigned to segments and a tree rooted at the pelvis; it never uses what a
marker means beyond that. The two shipped tables cover the Vicon Plug-in-Gait family used by the real data on
hand (Kinetics Toolkit tennis serve: ``LASI/RASI/LPSI/RPSI`` pelvis; CMU 41-marker set: ``LFWT/RFWT/LBWT/RBWT``).
Joint names follow the BVH naming the rest of Courtside uses (Hips, LeftUpLeg, ...).

Segment frames need, in order of preference: three markers (case 3); two markers plus the joint centre (case 2);
one marker plus the joint centre and a hinge axis (case 1). A hand with only a finger marker cannot be oriented,
so such markers are ``end`` sites of their parent (a bone tip for drawing), not segments.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SegmentSpec:
    """One body segment. ``markers`` define its frame (the first three are used); ``end`` is an optional marker
    whose mean position in this segment's frame becomes a BVH End Site (e.g. the toe, the head top)."""

    name: str
    parent: str | None
    markers: tuple[str, ...]
    end: str | None = None


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
        return names + [seg.end for seg in self.segments if seg.end]


def _plug_in_gait(name: str, pelvis: tuple[str, ...], shank: str, foot: tuple[str, ...]) -> MarkerSet:
    """Shared Plug-in-Gait layout; the variants differ only in pelvis, shank and foot marker names."""

    def side(s: str, segs: list[SegmentSpec]) -> None:
        side_name = "Left" if s == "L" else "Right"
        segs += [
            SegmentSpec(f"{side_name}UpLeg", "Hips", (f"{s}THI", f"{s}KNE")),
            SegmentSpec(f"{side_name}Leg", f"{side_name}UpLeg", (f"{s}{shank}", f"{s}ANK")),
            SegmentSpec(f"{side_name}Foot", f"{side_name}Leg", tuple(f"{s}{m}" for m in foot), end=f"{s}TOE"),
            SegmentSpec(f"{side_name}Arm", "Spine", (f"{s}UPA", f"{s}ELB")),
            SegmentSpec(f"{side_name}ForeArm", f"{side_name}Arm", (f"{s}WRA", f"{s}WRB", f"{s}FRM"), end=f"{s}FIN"),
        ]

    segments = [
        SegmentSpec("Hips", None, pelvis),
        SegmentSpec("Spine", "Hips", ("C7", "CLAV", "STRN", "T10")),
        SegmentSpec("Head", "Spine", ("LFHD", "RFHD", "LBHD", "RBHD")),
    ]
    side("L", segments)
    side("R", segments)
    return MarkerSet(name, tuple(segments))


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
