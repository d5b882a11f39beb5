"""Acclaim ASF (skeleton) / AMC (motion) reader for CMU and HDM05 data.

Conversion to the project's joint representation (see skeleton.py):

* every ASF bone becomes a joint at the bone's *proximal* end; the bone's vector `length * direction`
  (given in world axes at rest) is the offset of its children, and leaf bones get an `<name>_end` end site;
* a bone's local rotation is `C M C^-1`, where C comes from the bone's `axis` angles (applied in the
  order written after them, e.g. "XYZ" = X first, so C = Rz Ry Rx) and M from the AMC dof values (applied
  in dof-list order). The root uses `:root orientation`/`axis` and the `:root order` column layout;
* lengths: Acclaim lengths are inches times `:units length` (CMU/HDM05: 0.45), so
  metres = value / length * 0.0254 (root translations in the AMC too);
* angles: `:units angle deg|rad` for the ASF, the AMC's `:DEGREES`/`:RADIANS` header for the AMC
  (falling back to the ASF unit).

AMC files do not record the frame rate; CMU and HDM05 capture at 120 Hz, the default."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.errors import MalformedFileError
from engine.mocap.plausible import check_values
from engine.mocap import quaternions as quat
from engine.mocap.skeleton import Motion, Skeleton

INCH_M = 0.0254
_ROT_DOFS = {"rx": "X", "ry": "Y", "rz": "Z"}


@dataclass(frozen=True, eq=False)
class AsfSkeleton:
    """An ASF file converted to a Skeleton, plus what is needed to read AMC files against it."""

    skeleton: Skeleton
    path: str
    length_unit_m: float  # metres per ASF length unit
    angle_in_degrees: bool
    root_order: tuple[str, ...]  # AMC root columns, e.g. ("tx","ty","tz","rx","ry","rz")
    root_rotation_order: str  # `:root axis`, the order the root rotations are applied in, e.g. "XYZ"
    dofs: dict[str, tuple[str, ...]]  # bone name -> dof names in AMC column order
    axis_quats: dict[str, np.ndarray]  # joint name (incl. "root") -> C as a quaternion


def _read_lines(path: Path) -> list[str]:
    try:
        return path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as exc:
        raise MalformedFileError(path, None, f"cannot read file: {exc}") from None


def _floats(path: Path, line: int, fields: list[str], count: int, what: str) -> np.ndarray:
    try:
        vals = np.array([float(f) for f in fields[:count]])
    except ValueError:
        vals = np.array([])
    if vals.size != count:
        raise MalformedFileError(path, line, f"{what}: expected {count} numbers, got {' '.join(fields)!r}")
    check_values(path, vals, what, line)
    return vals


def _axis_quat(path: Path, line: int, fields: list[str], to_rad: float) -> np.ndarray:
    """`axis a b c ORDER` -> quaternion of C (rotations applied in ORDER, so product in reverse)."""
    angles = _floats(path, line, fields, 3, "axis angles") * to_rad
    order = fields[3].upper() if len(fields) > 3 else "XYZ"
    if sorted(order) != ["X", "Y", "Z"]:
        raise MalformedFileError(path, line, f"axis order must be a permutation of XYZ, got {order!r}")
    by_axis = dict(zip("XYZ", angles))
    applied = order[::-1]
    return quat.from_euler(np.array([by_axis[a] for a in applied]), applied)


def _sections(path: Path, lines: list[str]) -> dict[str, list[tuple[int, list[str]]]]:
    """Split an ASF into ':keyword' sections of (line number, fields), dropping comments."""
    sections: dict[str, list[tuple[int, list[str]]]] = {}
    current = None
    for number, text in enumerate(lines, start=1):
        body = text.split("#", 1)[0].strip()
        if not body:
            continue
        if body.startswith(":"):
            key, *rest = body.split()
            current = key[1:].lower()
            sections.setdefault(current, [])
            if rest:
                sections[current].append((number, rest))
        elif current is None:
            raise MalformedFileError(path, number, f"text before the first ':section': {body!r}")
        else:
            sections[current].append((number, body.split()))
    return sections


def read_asf(path: str | Path) -> AsfSkeleton:
    """Parse an ASF skeleton file (see module docstring for the conversion)."""
    path = Path(path)
    sections = _sections(path, _read_lines(path))
    for needed in ("root", "bonedata", "hierarchy"):
        if needed not in sections:
            raise MalformedFileError(path, None, f"missing :{needed} section")
    length_scale, degrees = 1.0, True
    for number, fields in sections.get("units", []):
        if fields[0] == "length":
            length_scale = float(_floats(path, number, fields[1:], 1, "length unit")[0])
            if length_scale <= 0:
                raise MalformedFileError(path, number, f"length unit must be positive, got {length_scale}")
        elif fields[0] == "angle":
            if len(fields) < 2 or fields[1].lower() not in ("deg", "rad"):
                raise MalformedFileError(path, number, f"angle unit must be deg or rad, got {' '.join(fields)!r}")
            degrees = fields[1].lower() == "deg"
    to_rad = np.pi / 180 if degrees else 1.0
    unit_m = INCH_M / length_scale

    root_order: tuple[str, ...] = ("tx", "ty", "tz", "rx", "ry", "rz")
    root_axis_order, root_orientation, root_position = "XYZ", np.zeros(3), np.zeros(3)
    orientation_line = None
    for number, fields in sections["root"]:
        key = fields[0].lower()
        if key == "order":
            root_order = tuple(f.lower() for f in fields[1:])
            if sorted(root_order) != ["rx", "ry", "rz", "tx", "ty", "tz"]:
                raise MalformedFileError(path, number, f"root order must list TX TY TZ RX RY RZ, got {fields[1:]}")
        elif key == "axis":
            root_axis_order = fields[1].upper() if len(fields) > 1 else ""
            if sorted(root_axis_order) != ["X", "Y", "Z"]:
                raise MalformedFileError(path, number, f"root axis must be a permutation of XYZ, got {fields[1:]}")
        elif key == "position":
            root_position = _floats(path, number, fields[1:], 3, "root position") * unit_m
        elif key == "orientation":
            root_orientation, orientation_line = fields[1:], number
    axis_quats = {"root": _axis_quat(path, orientation_line or 0, list(root_orientation) + [root_axis_order], to_rad)
                  if orientation_line else quat.identity()}

    bones: dict[str, dict] = {}
    block: dict | None = None
    for number, fields in sections["bonedata"]:
        key = fields[0].lower()
        if key == "begin":
            block = {"line": number, "dof": ()}
        elif key == "end":
            if block is None or "name" not in block:
                raise MalformedFileError(path, number, "bone block without a name")
            for k in ("direction", "length"):
                if k not in block:
                    raise MalformedFileError(path, block["line"], f"bone {block['name']!r} has no {k}")
            bones[block["name"]] = block
            block = None
        elif block is None:
            if key == "limits" or fields[0].startswith("("):
                continue
            raise MalformedFileError(path, number, f"{fields[0]!r} outside a begin/end bone block")
        elif key == "name":
            block["name"] = fields[1]
        elif key == "direction":
            d = _floats(path, number, fields[1:], 3, "direction")
            n = np.linalg.norm(d)
            block["direction"] = d / n if n > 0 else d
        elif key == "length":
            block["length"] = float(_floats(path, number, fields[1:], 1, "length")[0])
        elif key == "axis":
            block["axis"] = _axis_quat(path, number, fields[1:], to_rad)
        elif key == "dof":
            dofs = tuple(f.lower() for f in fields[1:])
            bad = [d for d in dofs if d not in _ROT_DOFS]
            if bad:
                raise MalformedFileError(path, number, f"unsupported dof(s) {bad} (only rx ry rz)")
            block["dof"] = dofs
    if block is not None:
        raise MalformedFileError(path, block["line"], "bone block not closed with 'end'")

    children: dict[str, list[str]] = {}
    for number, fields in sections["hierarchy"]:
        if fields[0].lower() in ("begin", "end"):
            continue
        for name in fields:
            if name != "root" and name not in bones:
                raise MalformedFileError(path, number, f"hierarchy names unknown bone {name!r}")
        if "root" in fields[1:]:
            raise MalformedFileError(path, number, f"hierarchy cycle: 'root' listed as a child of {fields[0]!r}")
        children.setdefault(fields[0], []).extend(fields[1:])

    names, parents, offsets, end_site = ["root"], [-1], [np.zeros(3)], [False]
    order_stack = [(c, 0) for c in reversed(children.get("root", []))]
    while order_stack:  # depth-first, so parents precede children and chains stay contiguous
        name, parent = order_stack.pop()
        if name in names:
            raise MalformedFileError(path, bones[name]["line"], f"bone {name!r} appears twice in the hierarchy")
        pb = names[parent]
        offset = root_position if pb == "root" else bones[pb]["length"] * bones[pb]["direction"] * unit_m
        names.append(name)
        parents.append(parent)
        offsets.append(offset)
        end_site.append(False)
        me = len(names) - 1
        kids = children.get(name, [])
        if not kids:
            names.append(name + "_end")
            parents.append(me)
            offsets.append(bones[name]["length"] * bones[name]["direction"] * unit_m)
            end_site.append(True)
        order_stack.extend((c, me) for c in reversed(kids))
    missing = sorted(set(bones) - set(names))
    if missing:
        raise MalformedFileError(path, None, f"bones not reachable from root in :hierarchy: {missing}")
    skeleton = Skeleton(tuple(names), np.array(parents), np.array(offsets), np.array(end_site))
    dofs = {"root": root_order, **{b: bones[b]["dof"] for b in bones}}
    axis_quats.update({b: bones[b].get("axis", quat.identity()) for b in bones})
    return AsfSkeleton(skeleton, str(path), unit_m, degrees, root_order, root_axis_order, dofs, axis_quats)


def _amc_columns(path: Path, lines: list[str], asf: AsfSkeleton) -> tuple[dict[str, np.ndarray], bool | None]:
    """Per-bone (F, ndof) value arrays, and the AMC's own angle unit if it declares one."""
    degrees: bool | None = None
    start = 0
    for start, text in enumerate(lines):
        body = text.strip()
        if body.startswith("#") or not body:
            continue
        if body.startswith(":"):
            if body.upper() == ":DEGREES":
                degrees = True
            elif body.upper() == ":RADIANS":
                degrees = False
            continue
        break
    else:
        raise MalformedFileError(path, None, "no frames")
    rows: dict[str, list[list[str]]] = {b: [] for b, d in asf.dofs.items() if d}
    rows_lines: dict[str, list[int]] = {b: [] for b in rows}
    frame_lines: list[int] = []
    for number, text in enumerate(lines[start:], start=start + 1):
        fields = text.split()
        if not fields:
            continue
        if len(fields) == 1 and fields[0].isdigit():
            frame_lines.append(number)
            continue
        name = fields[0]
        if not frame_lines:
            raise MalformedFileError(path, number, f"bone line before the first frame number: {text.strip()!r}")
        if name not in asf.dofs:
            raise MalformedFileError(path, number, f"unknown bone {name!r} (not in {asf.path})")
        if name not in rows:
            continue  # a bone with no dofs listed anyway
        want = len(asf.dofs[name])
        if len(fields) - 1 != want:
            raise MalformedFileError(path, number, f"bone {name!r} has {len(fields) - 1} values, expected {want}")
        if len(rows[name]) != len(frame_lines) - 1:
            raise MalformedFileError(path, number, f"bone {name!r} repeated or out of place in frame {len(frame_lines)}")
        rows[name].append(fields[1:])
        rows_lines[name].append(number)
    if not frame_lines:
        raise MalformedFileError(path, None, "no frames")
    out = {}
    for name, values in rows.items():
        if len(values) != len(frame_lines):
            where = frame_lines[len(values)] if len(values) < len(frame_lines) else None
            raise MalformedFileError(path, where, f"bone {name!r} missing from frame {len(values) + 1}")
        try:
            out[name] = np.array(values, dtype=float)
            check_values(path, out[name], f"bone {name!r}", np.array(rows_lines[name]))
        except ValueError as exc:
            if isinstance(exc, MalformedFileError):
                raise
            for row, number in zip(values, rows_lines[name]):
                try:
                    [float(v) for v in row]
                except ValueError:
                    raise MalformedFileError(path, number, f"bone {name!r} holds a non-number: {' '.join(row)!r}") from None
    return out, degrees


def read_amc(path: str | Path, asf: AsfSkeleton | str | Path, fps: float = 120.0, name: str | None = None) -> Motion:
    """Read an AMC motion against its ASF skeleton (an AsfSkeleton or the .asf path)."""
    path = Path(path)
    if not isinstance(asf, AsfSkeleton):
        asf = read_asf(asf)
    columns, amc_degrees = _amc_columns(path, _read_lines(path), asf)
    degrees = asf.angle_in_degrees if amc_degrees is None else amc_degrees
    to_rad = np.pi / 180 if degrees else 1.0
    skel = asf.skeleton
    n_frames = len(next(iter(columns.values())))
    rotations = quat.identity((n_frames, skel.n_joints))

    root = columns["root"]
    col = {d: i for i, d in enumerate(asf.root_order)}
    root_pos = root[:, [col["tx"], col["ty"], col["tz"]]] * asf.length_unit_m
    applied_order = asf.root_rotation_order
    _set_local(rotations, 0, root[:, [col["r" + a.lower()] for a in applied_order]] * to_rad, applied_order,
               asf.axis_quats["root"])
    for j, joint in enumerate(skel.names):
        if j == 0 or skel.end_site[j] or not asf.dofs.get(joint):
            continue
        order = "".join(_ROT_DOFS[d] for d in asf.dofs[joint])
        _set_local(rotations, j, columns[joint] * to_rad, order, asf.axis_quats[joint])
    return Motion(skel, fps, root_pos, quat.canonical_sign(rotations), name if name is not None else path.stem)


def _set_local(rotations: np.ndarray, joint: int, angles_rad: np.ndarray, applied_order: str, c: np.ndarray) -> None:
    """rotations[:, joint] = C M C^-1 with M applying `applied_order` axes first-to-last."""
    m = quat.from_euler(angles_rad[:, ::-1], applied_order[::-1])
    rotations[:, joint] = quat.multiply(quat.multiply(c, m), quat.conjugate(c))
