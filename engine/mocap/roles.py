"""Canonical joint roles, so engine code can say "right_elbow" without knowing whose skeleton it is.

Each role maps to the joint whose *position* is that landmark and whose *frame* moves with the segment
that starts there (e.g. `right_elbow` is the joint at the elbow, which carries the forearm). One explicit
table per naming convention (CMU ASF, CMU BVH as converted by cgspeed, Bandai Namco) rather than fuzzy name
matching: a wrong guess would silently put a sensor on the wrong bone. With CMU ASF bone-start joints
`lowerback` sits exactly on the root, so `lower_back`/`upper_back` use the next spine joints up (top of
lowerback / top of upperback) to give the error metric distinct points."""
from __future__ import annotations

import numpy as np

from engine.errors import CourtsideError

from engine.mocap.skeleton import Skeleton

# role -> joint name, per naming convention; "{L}"/"{l}" expand to the side.
_CONVENTIONS: dict[str, dict[str, str]] = {
    "cmu_asf": {"pelvis": "root", "lower_back": "upperback", "upper_back": "thorax", "neck": "lowerneck",
                "head": "head", "hip": "{l}femur", "knee": "{l}tibia", "ankle": "{l}foot", "toe": "{l}toes",
                "clavicle": "{l}clavicle", "shoulder": "{l}humerus", "elbow": "{l}radius", "wrist": "{l}wrist",
                "hand": "{l}hand"},
    "cmu_bvh": {"pelvis": "Hips", "lower_back": "Chest", "upper_back": "Chest2", "neck": "Neck", "head": "Head",
                "hip": "{Left}Hip", "knee": "{Left}Knee", "ankle": "{Left}Ankle", "toe": "{Left}Toe",
                "clavicle": "{Left}Collar", "shoulder": "{Left}Shoulder", "elbow": "{Left}Elbow",
                "wrist": "{Left}Wrist", "hand": "{l}hand"},
    "bandai": {"pelvis": "Hips", "lower_back": "Spine", "upper_back": "Chest", "neck": "Neck", "head": "Head",
               "hip": "UpperLeg_{L}", "knee": "LowerLeg_{L}", "ankle": "Foot_{L}", "toe": "Toes_{L}",
               "clavicle": "Shoulder_{L}", "shoulder": "UpperArm_{L}", "elbow": "LowerArm_{L}",
               "wrist": "Hand_{L}", "hand": "Hand_{L}_end"},
}
_PARTS = ("hip", "knee", "ankle", "toe", "clavicle", "shoulder", "elbow", "wrist", "hand")
_SIDES = {"left": {"l": "l", "L": "L", "Left": "Left"}, "right": {"l": "r", "L": "R", "Left": "Right"}}

ROLES: tuple[str, ...] = ("pelvis", "lower_back", "upper_back", "neck", "head") + tuple(
    f"{s}_{p}" for s in _SIDES for p in _PARTS)

# Seed 000 / Tautges error joints: pelvis, lower/upper back, neck, head, femur, tibia, foot, toes, clavicle,
# humerus, radius, hand (both sides), i.e. the segment-start joints of those bones.
ERROR_ROLES: tuple[str, ...] = ("pelvis", "lower_back", "upper_back", "neck", "head") + tuple(
    f"{s}_{p}" for s in _SIDES for p in ("hip", "knee", "ankle", "toe", "clavicle", "shoulder", "elbow", "hand"))


class UnknownSkeletonError(CourtsideError, ValueError):
    """The skeleton's joint names match none of the known conventions (so no joint has a role)."""


def _role_names(convention: dict[str, str]) -> dict[str, str]:
    out = {r: convention[r] for r in ROLES[:5]}
    for side, fill in _SIDES.items():
        for part in _PARTS:
            out[f"{side}_{part}"] = convention[part].format(**fill)
    return out


def joint_roles(skeleton: Skeleton) -> dict[str, int]:
    """Role name -> joint index for every role in ROLES, for CMU ASF, CMU BVH or Bandai skeletons.

    The convention is the first one whose names are all present (ValueError listing what is missing
    from the closest one otherwise)."""
    index = {n: j for j, n in enumerate(skeleton.names)}
    best: tuple[int, str, list[str]] | None = None
    for convention, table in _CONVENTIONS.items():
        names = _role_names(table)
        missing = [n for n in names.values() if n not in index]
        if not missing:
            return {role: index[name] for role, name in names.items()}
        if best is None or len(missing) < best[0]:
            best = (len(missing), convention, missing)
    raise UnknownSkeletonError(f"skeleton matches no known naming convention (closest: {best[1]}, missing joints "
                     f"{best[2]}; joints: {', '.join(skeleton.names)})")


def error_joint_indices(skeleton: Skeleton) -> np.ndarray:
    """Indices of the seed-000/Tautges evaluation joints (ERROR_ROLES order)."""
    roles = joint_roles(skeleton)
    return np.array([roles[r] for r in ERROR_ROLES])


def left_right_pairs(skeleton: Skeleton) -> list[tuple[int, int]]:
    """Every (left, right) joint pair by name (l/r prefix, Left/Right, _L/_R), for mirroring."""
    names = skeleton.names
    index = {n: j for j, n in enumerate(names)}
    pairs = []
    for j, n in enumerate(names):
        for left, right in (("Left", "Right"), ("_L", "_R"), ("L", "R")):
            if left in n:
                other = n.replace(left, right, 1)
                if other in index and other != n:
                    pairs.append((j, index[other]))
                    break
        else:
            if n[:1] == "l" and "r" + n[1:] in index and n not in ("lowerback", "lowerneck"):
                pairs.append((j, index["r" + n[1:]]))
    return pairs
