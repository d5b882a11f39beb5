"""BVH reader and writer.

Reader: any hierarchy, any per-joint rotation order, 3 or 6 channels per joint. Channel values that set a
joint's translation *replace* its header OFFSET (the convention of Bandai Namco's files, whose `Hips`
position channels carry the trajectory while `joint_Root` stays at the origin). Two cases are normalised
so that joint 0 is always the pelvis and carries all the translation:

* the root has exactly one child and that child has position channels (Bandai's `joint_Root` -> `Hips`):
  the two are merged, the child's world transform (root ∘ child) becomes the new root;
* non-root position channels must be constant over the clip (they are then a fixed offset); varying ones
  are rejected because the project's `Motion` only animates the root's translation.

Units: `scale` converts file units to metres. With `scale=None` it is chosen from KNOWN_UNITS so that the
skeleton's standing height is closest to 1.7 m (see `_guess_scale`): centimetres for Bandai, the CMU unit
(1/0.45 inch = 0.056444 m) for CMU BVH, inches, millimetres or metres otherwise.

Writer: root with 6 channels, other joints 3 rotation channels in one order, end sites as `End Site`;
values in centimetres by default (what Blender and most tools expect)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.errors import MalformedFileError
from engine.mocap import quaternions as quat
from engine.mocap.plausible import check_values
from engine.mocap.skeleton import Motion, Skeleton, forward_kinematics

CMU_UNIT_M = 0.0254 / 0.45  # CMU length unit: 0.45 scale on inches -> metres per unit (0.056444)
KNOWN_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254, "cmu": CMU_UNIT_M}
_POSITION = {"xposition": 0, "yposition": 1, "zposition": 2}
_ROTATION = {"xrotation": "X", "yrotation": "Y", "zrotation": "Z"}


class _Joint:
    def __init__(self, name: str, parent: int, line: int) -> None:
        self.name, self.parent, self.line = name, parent, line
        self.offset = np.zeros(3)
        self.channels: list[str] = []
        self.end_site = False


def _tokens(lines: list[str]) -> list[tuple[str, int]]:
    """(token, 1-based line) pairs; braces are split off even when glued to a word."""
    out = []
    for number, text in enumerate(lines, start=1):
        out.extend((tok, number) for tok in text.replace("{", " { ").replace("}", " } ").split())
    return out


def _parse_hierarchy(path: Path, lines: list[str]) -> tuple[list[_Joint], int]:
    """Joints in file (= topological) order, and the index of the MOTION line."""
    try:
        motion_line = next(i for i, l in enumerate(lines) if l.strip().upper() == "MOTION")
    except StopIteration:
        raise MalformedFileError(path, None, "no MOTION section") from None
    toks = _tokens(lines[:motion_line])
    if not toks or toks[0][0].upper() != "HIERARCHY":
        raise MalformedFileError(path, toks[0][1] if toks else 1, "file does not start with HIERARCHY")
    joints: list[_Joint] = []
    stack: list[int] = []
    i = 1
    pending: _Joint | None = None

    def need(k: int, what: str) -> list[tuple[str, int]]:
        if i + k > len(toks):
            raise MalformedFileError(path, toks[-1][1], f"hierarchy ends early, expected {what}")
        return toks[i:i + k]

    while i < len(toks):
        tok, line = toks[i]
        key = tok.upper()
        if key in ("ROOT", "JOINT"):
            if (key == "ROOT") != (not stack) or (key == "ROOT" and joints):
                raise MalformedFileError(path, line, f"{tok} in the wrong place (one ROOT, then JOINTs inside it)")
            name = need(2, "a joint name")[1][0]
            pending = _Joint(name, stack[-1] if stack else -1, line)
            i += 2
        elif key == "END":
            if not stack or need(2, "'End Site'")[1][0].upper() != "SITE":
                raise MalformedFileError(path, line, "'End' must be 'End Site' inside a joint")
            pending = _Joint(joints[stack[-1]].name + "_end", stack[-1], line)
            pending.end_site = True
            i += 2
        elif tok == "{":
            if pending is None:
                raise MalformedFileError(path, line, "'{' without a joint")
            joints.append(pending)
            stack.append(len(joints) - 1)
            pending = None
            i += 1
        elif tok == "}":
            if not stack:
                raise MalformedFileError(path, line, "unbalanced '}'")
            stack.pop()
            i += 1
        elif key == "OFFSET":
            vals = need(4, "three OFFSET numbers")[1:]
            try:
                joints[stack[-1]].offset = np.array([float(v) for v, _ in vals])
            except (ValueError, IndexError):
                raise MalformedFileError(path, line, f"bad OFFSET {' '.join(v for v, _ in vals)!r}") from None
            check_values(path, joints[stack[-1]].offset, "OFFSET", line)
            i += 4
        elif key == "CHANNELS":
            try:
                count = int(need(2, "a channel count")[1][0])
            except ValueError:
                raise MalformedFileError(path, line, f"bad channel count {toks[i + 1][0]!r}") from None
            names = [t.lower() for t, _ in need(2 + count, f"{count} channel names")[2:]]
            bad = [n for n in names if n not in _POSITION and n not in _ROTATION]
            if not stack or bad:
                raise MalformedFileError(path, line, f"unknown channel(s) {bad}" if bad else "CHANNELS outside a joint")
            joints[stack[-1]].channels = names
            i += 2 + count
        else:
            raise MalformedFileError(path, line, f"unexpected token {tok!r} in HIERARCHY")
    if stack or pending is not None:
        raise MalformedFileError(path, motion_line + 1, "unbalanced braces: hierarchy not closed before MOTION")
    if not joints:
        raise MalformedFileError(path, motion_line + 1, "no joints in HIERARCHY")
    return joints, motion_line


def _parse_motion(path: Path, lines: list[str], motion_line: int, n_channels: int) -> tuple[np.ndarray, float]:
    header = [(i, lines[i].strip()) for i in range(motion_line + 1, min(motion_line + 3, len(lines)))]
    if len(header) < 2 or not header[0][1].lower().startswith("frames:") or not header[1][1].lower().startswith("frame time:"):
        raise MalformedFileError(path, motion_line + 2, "expected 'Frames:' and 'Frame Time:' after MOTION")
    try:
        n_frames = int(header[0][1].split(":", 1)[1])
        frame_time = float(header[1][1].split(":", 1)[1])
    except ValueError:
        raise MalformedFileError(path, motion_line + 2, "bad 'Frames:' or 'Frame Time:' value") from None
    if n_frames < 1 or not 0 < frame_time < np.inf:
        raise MalformedFileError(path, motion_line + 2, f"need Frames >= 1 and Frame Time > 0, got {n_frames}, {frame_time}")
    first = motion_line + 3
    body = lines[first:]
    while body and not body[-1].strip():
        body.pop()
    try:
        values = np.array(" ".join(body).split(), dtype=float)
        ok = values.size == n_frames * n_channels and len(body) == n_frames
    except ValueError:
        ok = False
    if not ok:  # find the first offending line for the message
        for k, text in enumerate(body[:n_frames]):
            fields = text.split()
            if len(fields) != n_channels:
                raise MalformedFileError(path, first + k + 1, f"frame {k} has {len(fields)} values, expected {n_channels}")
            try:
                [float(f) for f in fields]
            except ValueError:
                raise MalformedFileError(path, first + k + 1, f"frame {k} holds a non-number") from None
        raise MalformedFileError(path, first + len(body), f"header says {n_frames} frames, file holds {len(body)}")
    values = values.reshape(n_frames, n_channels)
    check_values(path, values, "channel value", first + 1 + np.arange(n_frames))
    return values, frame_time


def _guess_scale(skeleton: Skeleton, root_pos: np.ndarray, rotations: np.ndarray) -> float:
    """Pick the KNOWN_UNITS factor that makes the body's vertical extent closest to 1.7 m (log distance).

    Uses the largest vertical extent over a few frames spread through the clip, so a crouch or a lying
    rest pose in the file does not matter."""
    pick = np.unique(np.linspace(0, len(root_pos) - 1, 9).astype(int))
    pos, _ = forward_kinematics(Motion(skeleton, 1.0, root_pos[pick], rotations[pick]))
    height = float(np.max(pos[..., 1].max(axis=1) - pos[..., 1].min(axis=1)))
    if not height > 0:
        return 1.0
    return min(KNOWN_UNITS.values(), key=lambda s: abs(np.log(height * s / 1.7)))


def read_bvh(path: str | Path, scale: float | str | None = None, name: str | None = None) -> Motion:
    """Read a BVH file into a Motion in metres. `scale`: factor to metres, a KNOWN_UNITS key, or None (guess)."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as exc:
        raise MalformedFileError(path, None, f"cannot read file: {exc}") from None
    joints, motion_line = _parse_hierarchy(path, lines)
    n_channels = sum(len(j.channels) for j in joints)
    data, frame_time = _parse_motion(path, lines, motion_line, n_channels)
    n_frames = data.shape[0]

    translations = np.repeat(np.array([j.offset for j in joints])[None], n_frames, axis=0)  # (F, J, 3)
    rotations = quat.identity((n_frames, len(joints)))
    col = 0
    for k, joint in enumerate(joints):
        chans = joint.channels
        cols = np.arange(col, col + len(chans))
        col += len(chans)
        for c, ch in zip(cols, chans):
            if ch in _POSITION:
                translations[:, k, _POSITION[ch]] = data[:, c]
        rot = [(c, _ROTATION[ch]) for c, ch in zip(cols, chans) if ch in _ROTATION]
        if rot:
            rotations[:, k] = quat.from_euler(np.radians(data[:, [c for c, _ in rot]]), "".join(a for _, a in rot))
    rotations = quat.canonical_sign(rotations)

    names = [j.name for j in joints]
    parents = np.array([j.parent for j in joints])
    has_pos = np.array([any(c in _POSITION for c in j.channels) for j in joints])
    root_children = np.flatnonzero(parents == 0)
    if len(root_children) == 1 and root_children[0] == 1 and has_pos[1]:
        # Merge a bare root into its only child (Bandai joint_Root -> Hips): world = root ∘ child.
        r0 = rotations[:, 0]
        translations[:, 1] = translations[:, 0] + quat.rotate(r0, translations[:, 1])
        rotations[:, 1] = quat.canonical_sign(quat.multiply(r0, rotations[:, 1]))
        keep = np.arange(1, len(joints))
        names = names[1:]
        parents = np.where(parents[keep] > 0, parents[keep] - 1, -1)
        translations, rotations, has_pos = translations[:, keep], rotations[:, keep], has_pos[keep]
        joints = joints[1:]
    for k in np.flatnonzero(has_pos[1:]) + 1:
        spread = np.ptp(translations[:, k], axis=0).max()
        if spread > 1e-4 * max(1.0, np.abs(translations[:, k]).max()):
            raise MalformedFileError(path, joints[k].line,
                                     f"joint {names[k]!r} has varying position channels (range {spread:g}); "
                                     "only the root may translate")
    offsets = translations[0].copy()
    offsets[0] = joints[0].offset  # the root's header OFFSET; its channels are the trajectory
    skeleton = Skeleton(tuple(names), parents, offsets, np.array([j.end_site for j in joints]))
    root_pos = translations[:, 0].copy()
    if scale is None:
        factor = _guess_scale(skeleton, root_pos, rotations)
    elif isinstance(scale, str):
        if scale not in KNOWN_UNITS:
            raise ValueError(f"unknown unit {scale!r}; known: {sorted(KNOWN_UNITS)}")
        factor = KNOWN_UNITS[scale]
    else:
        factor = float(scale)
    return Motion(skeleton.scaled(factor), 1.0 / frame_time, root_pos * factor, rotations,
                  name if name is not None else path.stem)


def bvh_frame_values(motion: Motion, order: str = "ZYX", units: str = "cm") -> np.ndarray:
    """(F, C) channel values of the MOTION lines `write_bvh` writes (root position in `units`, then each animated
    joint's rotation in degrees, intrinsic `order`); also what a live BVH stream sends per frame."""
    animated = np.flatnonzero(~motion.skeleton.end_site)
    euler = np.degrees(quat.to_euler(motion.rotations[:, animated], order.upper()))  # (F, A, 3)
    return np.concatenate([motion.root_positions_m / KNOWN_UNITS[units], euler.reshape(motion.n_frames, -1)], axis=1)


def write_bvh(path: str | Path, motion: Motion, order: str = "ZYX", units: str = "cm") -> None:
    """Write a Motion as BVH (root 6 channels, joints 3, given intrinsic rotation order, values in `units`)."""
    order = order.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise ValueError(f"rotation order must be a permutation of XYZ, got {order!r}")
    per_m = 1.0 / KNOWN_UNITS[units]
    skel = motion.skeleton
    rot_names = " ".join(f"{a}rotation" for a in order)
    out = ["HIERARCHY"]
    depth_of = np.zeros(skel.n_joints, int)
    open_stack: list[int] = []
    for j in range(skel.n_joints):
        while open_stack and open_stack[-1] != skel.parents[j]:
            open_stack.pop()
            out.append("  " * len(open_stack) + "}")
        depth_of[j] = len(open_stack)
        pad = "  " * depth_of[j]
        off = " ".join(f"{v:.10g}" for v in skel.offsets_m[j] * per_m)
        if j == 0:
            out += [f"ROOT {skel.names[0]}", "{", f"  OFFSET {off}", f"  CHANNELS 6 Xposition Yposition Zposition {rot_names}"]
        elif skel.end_site[j]:
            out += [f"{pad}End Site", f"{pad}{{", f"{pad}  OFFSET {off}"]
        else:
            out += [f"{pad}JOINT {skel.names[j]}", f"{pad}{{", f"{pad}  OFFSET {off}", f"{pad}  CHANNELS 3 {rot_names}"]
        open_stack.append(j)
    while open_stack:
        open_stack.pop()
        out.append("  " * len(open_stack) + "}")
    frames = bvh_frame_values(motion, order, units)
    out += ["MOTION", f"Frames: {motion.n_frames}", f"Frame Time: {1.0 / motion.fps:.10g}"]
    out += [" ".join(f"{v:.10g}" for v in row) for row in frames]
    Path(path).write_text("\n".join(out) + "\n", encoding="utf-8")
