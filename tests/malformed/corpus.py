"""The malformed-input corpus, generated: valid files of every format the project reads, then mutated.

Each `Case` is one bad file (or bad argument) and the command that reads it. The corpus test runs every case
through the real CLI entry point and checks the contract every CLI promises: non-zero exit, exactly one line on
stderr naming the file and the problem, no traceback, and no output left half-written.

The valid bases come from the project's own writers (write_bvh, write_c3d, the recorder, build-graph) or from the
shipped CMU files, so a mutation is the only thing wrong with each file.
"""
from __future__ import annotations

import io
import json
import pickle
import struct
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from engine.mocap import (MarkerData, load_clip, sample_clips, standard_placements, virtual_accelerometers,
                          write_bvh)
from engine.mocap.clips import DATA_DIR
from engine.mocap.skeleton import Motion


@dataclass
class Case:
    family: str
    name: str
    files: dict[str, bytes]  # path relative to the case directory -> content
    argv: list[str]  # "{d}" is replaced by the case directory
    bad: str  # what the one stderr line must name (a path relative to the case directory, or a literal)
    runner: str = "courtside"  # courtside (the dispatcher) | mocap (python -m engine.mocap)
    outputs: tuple[str, ...] = ()  # must not exist afterwards (nothing half-written)
    shared: dict[str, str] = field(default_factory=dict)  # name in the case dir -> path of a shared valid file

    @property
    def id(self) -> str:
        return f"{self.family}-{self.name}"


# ----------------------------------------------------------------------------------------------- valid bases
def _short_motion(frames: int = 12) -> Motion:
    m = load_clip(sample_clips()["16_01"], fps=30.0)
    return Motion(m.skeleton, m.fps, m.root_positions_m[:frames], m.rotations[:frames], "short")


def valid_bvh_text() -> str:
    """A 12-frame BVH written by `write_bvh` (it needs a path: a temporary directory)."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "x.bvh"
        write_bvh(path, _short_motion())
        return path.read_text()


def valid_asf_text() -> str:
    return (DATA_DIR / "cmu" / "16.asf").read_text()


def valid_amc_text(frames: int = 8) -> str:
    lines = (DATA_DIR / "cmu" / "16_01.amc").read_text().splitlines()
    out = []
    for line in lines:
        if line.strip() == str(frames + 1):
            break
        out.append(line)
    return "\n".join(out) + "\n"


def valid_c3d_bytes(frames: int = 120, change: Callable[[np.ndarray], np.ndarray] | None = None) -> bytes:
    """Six markers moving smoothly; ``change(positions_m)`` makes an implausible variant of the same file."""
    import tempfile

    from engine.labeling.c3d_io import write_c3d

    rng = np.random.default_rng(0)
    labels = tuple(f"P:M{i}" for i in range(6))
    base = rng.normal(0, 0.3, (6, 3)) + [0, 0, 1.0]
    t = np.arange(frames)[:, None, None] / 100.0
    pos = base[None] + 0.2 * np.sin(2 * np.pi * 0.5 * t + np.arange(6)[None, :, None])
    pos = change(pos) if change is not None else pos
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "x.c3d"
        write_c3d(path, MarkerData(labels, pos, 100.0, "x"))
        return path.read_bytes()


def take_arrays(seconds: float = 2.0, fps: float = 120.0) -> dict[str, np.ndarray]:
    """A synthesis input (virtual accelerometers of a shipped clip) of `seconds`."""
    m = load_clip(sample_clips()["16_05"], fps=fps)
    n = int(seconds * fps)
    m = Motion(m.skeleton, fps, m.root_positions_m[:n], m.rotations[:n], "take")
    acc = virtual_accelerometers(m, standard_placements(m.skeleton))
    return {"acc_g": acc, "fps": np.array(fps), "position_m": m.root_positions_m[:, [0, 2]]}


def _npz(**arrays) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _npz_pickled(**arrays) -> bytes:
    """An npz holding an object array (needs pickle to load: must be refused, never unpickled)."""
    buf = io.BytesIO()
    np.savez(buf, **{k: np.array(v, dtype=object) if k == "acc_g" else v for k, v in arrays.items()})
    return buf.getvalue()


def valid_calibration_record() -> dict:
    m = load_clip(sample_clips()["16_01"], fps=30.0)
    sensors = {}
    for i, p in enumerate(standard_placements(m.skeleton, ["left_forearm", "right_forearm", "chest"])):
        sensors[f"st1/{i}"] = {"segment": p.name, "rotation": p.rotation.tolist(), "gravity_sensor_g": [0, 0, 1],
                               "norm_error_g": 0.0, "correction_deg": 0.0, "passed": True}
    return {"schema": "courtside.sensor_calibration", "schema_version": 1, "quality_score": 1.0, "grade": "A",
            "passed": True, "sensors": sensors}


def _body(header: dict) -> bytes:
    """A codec body with exactly this header and no payload (to declare arrays that are not there)."""
    text = json.dumps(header).encode()
    return struct.pack(">I", len(text)) + text


def recording_bytes(meta: bytes, bodies: list[bytes], magic: bytes = b"CSREC\x00\x01\n") -> bytes:
    out = magic + struct.pack(">I", len(meta)) + meta + struct.pack(">I", zlib.crc32(meta))
    for body in bodies:
        out += struct.pack(">4sII", b"CHNK", len(body), zlib.crc32(body)) + body
    return out


# ----------------------------------------------------------------------------------------------- families
def _replace_line(text: str, predicate: Callable[[str], bool], new: str | None, nth: int = 0) -> str:
    lines = text.splitlines()
    hits = [i for i, line in enumerate(lines) if predicate(line)]
    i = hits[nth]
    if new is None:
        del lines[i]
    else:
        lines[i] = new
    return "\n".join(lines) + "\n"


def bvh_cases() -> list[Case]:
    good = valid_bvh_text()
    lines = good.splitlines()
    motion_at = lines.index("MOTION")
    first_frame = motion_at + 3
    row = lines[first_frame].split()

    def frame_value(value: str, row_index: int = 2, column: int = 4) -> str:
        out = list(lines)
        fields = out[first_frame + row_index].split()
        fields[column] = value
        out[first_frame + row_index] = " ".join(fields)
        return "\n".join(out) + "\n"

    mutations: dict[str, str | bytes] = {
        "empty": "",
        "binary": bytes(range(256)) * 4,
        "utf16": good.encode("utf-16"),
        "no-motion": "\n".join(lines[:motion_at]) + "\n",
        "no-hierarchy": "\n".join(lines[motion_at:]) + "\n",
        "frames-zero": _replace_line(good, lambda l: l.startswith("Frames:"), "Frames: 0"),
        "frames-negative": _replace_line(good, lambda l: l.startswith("Frames:"), "Frames: -3"),
        "frames-text": _replace_line(good, lambda l: l.startswith("Frames:"), "Frames: many"),
        "frames-more-than-rows": _replace_line(good, lambda l: l.startswith("Frames:"), "Frames: 40"),
        "frames-fewer-than-rows": _replace_line(good, lambda l: l.startswith("Frames:"), "Frames: 5"),
        "frames-huge": _replace_line(good, lambda l: l.startswith("Frames:"), "Frames: 1000000000000"),
        "frame-time-zero": _replace_line(good, lambda l: l.startswith("Frame Time:"), "Frame Time: 0"),
        "frame-time-nan": _replace_line(good, lambda l: l.startswith("Frame Time:"), "Frame Time: nan"),
        "frame-time-inf": _replace_line(good, lambda l: l.startswith("Frame Time:"), "Frame Time: inf"),
        "frame-time-negative": _replace_line(good, lambda l: l.startswith("Frame Time:"), "Frame Time: -0.01"),
        "frame-time-missing": _replace_line(good, lambda l: l.startswith("Frame Time:"), None),
        "row-short": frame_value("", 3, 0),
        "row-long": _replace_line(good, lambda l: l == lines[first_frame + 1], lines[first_frame + 1] + " 1.0"),
        "row-text": frame_value("abc"),
        "value-nan": frame_value("nan"),
        "value-inf": frame_value("inf"),
        "value-minus-inf": frame_value("-inf"),
        "value-1e300": frame_value("1e300"),
        "root-position-1e300": frame_value("1e300", 1, 0),
        "value-hex": frame_value("0x1F"),
        "offset-two-numbers": _replace_line(good, lambda l: l.strip().startswith("OFFSET"), "  OFFSET 0 0", 1),
        "offset-nan": _replace_line(good, lambda l: l.strip().startswith("OFFSET"), "  OFFSET nan 0 0", 1),
        "offset-inf": _replace_line(good, lambda l: l.strip().startswith("OFFSET"), "  OFFSET 0 inf 0", 2),
        "offset-1e300": _replace_line(good, lambda l: l.strip().startswith("OFFSET"), "  OFFSET 0 1e300 0", 2),
        "channels-unknown": _replace_line(good, lambda l: l.strip().startswith("CHANNELS 3"),
                                          "    CHANNELS 3 Zrotation Yrotation Wrotation", 0),
        "channels-count-text": _replace_line(good, lambda l: l.strip().startswith("CHANNELS 3"),
                                             "    CHANNELS three Zrotation Yrotation Xrotation", 0),
        "channels-count-wrong": _replace_line(good, lambda l: l.strip().startswith("CHANNELS 3"),
                                              "    CHANNELS 4 Zrotation Yrotation Xrotation", 0),
        "brace-missing": _replace_line(good, lambda l: l.strip() == "}", None, 0),
        "brace-extra": _replace_line(good, lambda l: l.strip() == "}", "}\n}", 0),
        "two-roots": good.replace("MOTION", "ROOT Extra\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Zrotation Yrotation Xrotation\n}\nMOTION", 1),
        "joint-no-name": _replace_line(good, lambda l: l.strip().startswith("JOINT"), "  JOINT", 0),
        "unknown-keyword": good.replace("HIERARCHY", "HIERARCHY\nBANANA", 1),
        "truncated-half": good[: len(good) // 2],
        "truncated-mid-row": good[: good.rindex("\n", 0, len(good) - 10) + 7],
        "all-values-nan": "\n".join(lines[:first_frame] + [" ".join(["nan"] * len(row))] * (len(lines) - first_frame)) + "\n",
    }
    cases = []
    for name, content in mutations.items():
        data = content.encode() if isinstance(content, str) else content
        cases.append(Case("bvh", name, {"clip.bvh": data}, ["info", "{d}/clip.bvh"], "clip.bvh", runner="mocap"))
    # the same file through conversion and graph building: no output may be left behind
    for name in ("value-nan", "truncated-half", "frames-more-than-rows", "value-1e300"):
        data = mutations[name].encode()
        cases.append(Case("bvh", f"convert-{name}", {"clip.bvh": data}, ["convert", "{d}/clip.bvh", "{d}/out.bvh"],
                          "clip.bvh", runner="mocap", outputs=("out.bvh",)))
        cases.append(Case("bvh", f"build-graph-{name}", {"clip.bvh": data}, ["build-graph", "{d}/clip.bvh", "-o",
                                                                             "{d}/g.npz"], "clip.bvh",
                          outputs=("g.npz", "g.json")))
    # a valid BVH whose joint names match no convention: fine to inspect, but no sensor can be placed on it
    renamed = good
    for i, joint in enumerate(sorted({l.split()[1] for l in lines[:motion_at] if l.strip().split()[:1] in (["JOINT"], ["ROOT"])},
                                     key=len, reverse=True)):
        renamed = renamed.replace(f" {joint}\n", f" J{i}\n")
    cases.append(Case("bvh", "unknown-convention-build-graph", {"clip.bvh": renamed.encode()},
                      ["build-graph", "{d}/clip.bvh", "-o", "{d}/g.npz"], "clip.bvh", outputs=("g.npz", "g.json")))
    cases.append(Case("bvh", "directory", {"clip.bvh/x": b""}, ["info", "{d}/clip.bvh"], "clip.bvh", runner="mocap"))
    cases.append(Case("bvh", "missing", {}, ["info", "{d}/clip.bvh"], "clip.bvh", runner="mocap"))
    cases.append(Case("bvh", "wrong-extension", {"clip.fbx": good.encode()}, ["info", "{d}/clip.fbx"], "clip.fbx",
                      runner="mocap"))
    return cases


def asf_amc_cases() -> list[Case]:
    asf, amc = valid_asf_text(), valid_amc_text()

    def sub(text: str, old: str, new: str) -> str:
        assert old in text, old
        return text.replace(old, new, 1)

    asf_mutations = {
        "empty": "",
        "binary": bytes(range(256)) * 4,
        "no-root": sub(asf, ":root", ":roots"),
        "no-bonedata": sub(asf, ":bonedata", ":bonedatas"),
        "no-hierarchy": sub(asf, ":hierarchy", ":hierarchies"),
        "text-before-section": "hello\n" + asf,
        "length-unit-zero": sub(asf, "length 0.45", "length 0"),
        "length-unit-text": sub(asf, "length 0.45", "length big"),
        "length-unit-nan": sub(asf, "length 0.45", "length nan"),
        "angle-unit-bad": sub(asf, "angle deg", "angle grad"),
        "root-order-bad": sub(asf, "order TX TY TZ RX RY RZ", "order TX TY TZ RX RY"),
        "root-axis-bad": sub(asf, "axis XYZ\n", "axis XXY\n"),
        "root-position-short": sub(asf, "position 0 0 0", "position 0 0"),
        "bone-no-name": sub(asf, "name lhipjoint\n", ""),
        "bone-no-length": sub(asf, "length 2.47672", ""),
        "bone-length-nan": sub(asf, "length 2.47672", "length nan"),
        "bone-direction-inf": sub(asf, "direction 0.635348 -0.713158 0.296208", "direction inf 0 0"),
        "bone-direction-short": sub(asf, "direction 0.635348 -0.713158 0.296208", "direction 0.6 -0.7"),
        "bone-axis-order-bad": sub(asf, "axis 0 0 0  XYZ", "axis 0 0 0  XYW"),
        "bone-dof-translation": sub(asf, "dof rx ry rz", "dof tx ry rz"),
        "bone-not-closed": asf[: asf.index(":hierarchy")] + "  begin\n     name extra\n:hierarchy" + asf[asf.index(":hierarchy") + 10:],
        "hierarchy-unknown-bone": sub(asf, "root lhipjoint", "root lhipjoint nosuchbone"),
        "hierarchy-cycle-to-root": sub(asf, "lhipjoint lfemur", "lhipjoint lfemur root"),
        "hierarchy-cycle": sub(asf, "lfemur ltibia", "lfemur ltibia lhipjoint"),
        "hierarchy-bone-twice": sub(asf, "lfemur ltibia", "lfemur ltibia rfemur"),
        "hierarchy-unreachable": sub(asf, "root lhipjoint", "root"),
        "truncated-half": asf[: len(asf) // 2],
    }
    cases = []
    for name, content in asf_mutations.items():
        data = content.encode() if isinstance(content, str) else content
        cases.append(Case("asf", name, {"16.asf": data, "16_01.amc": amc.encode()}, ["info", "{d}/16_01.amc"],
                          "16.asf", runner="mocap"))
    lines = amc.splitlines()
    first_bone = next(i for i, l in enumerate(lines) if l.startswith("lowerback"))

    def amc_line(i: int, new: str | None) -> str:
        out = list(lines)
        if new is None:
            del out[i]
        else:
            out[i] = new
        return "\n".join(out) + "\n"

    amc_mutations = {
        "empty": "",
        "binary": bytes(range(1, 256)) * 4,
        "header-only": "\n".join(lines[:3]) + "\n",
        "unknown-bone": amc_line(first_bone, "spine 1 2 3"),
        "too-few-values": amc_line(first_bone, "lowerback 4.1 -0.3"),
        "too-many-values": amc_line(first_bone, "lowerback 4.1 -0.3 1 2"),
        "non-number": amc_line(first_bone, "lowerback 4.1 x 1"),
        "nan-value": amc_line(first_bone, "lowerback nan 0 0"),
        "inf-value": amc_line(first_bone, "lowerback inf 0 0"),
        "huge-value": amc_line(first_bone, "lowerback 1e300 0 0"),
        "root-nan": amc_line(first_bone - 1, "root nan 17.8 -16.2 5.6 -0.99 -0.33"),
        "bone-missing": amc_line(first_bone, None),
        "bone-repeated": amc_line(first_bone, lines[first_bone] + "\n" + lines[first_bone]),
        "bone-before-frame": "\n".join(lines[:3] + [lines[first_bone]] + lines[3:]) + "\n",
        "all-nan": "\n".join(lines[:3] + [(l.split()[0] + " " + " ".join(["nan"] * (len(l.split()) - 1))) if not l.strip().isdigit() else l for l in lines[3:]]) + "\n",
        "truncated-half": amc[: len(amc) // 2 + 7],
    }
    for name, content in amc_mutations.items():
        data = content.encode() if isinstance(content, str) else content
        cases.append(Case("amc", name, {"16.asf": asf.encode(), "16_01.amc": data}, ["info", "{d}/16_01.amc"],
                          "16_01.amc", runner="mocap"))
    for name in ("nan-value", "all-nan", "truncated-half"):
        cases.append(Case("amc", f"build-graph-{name}", {"16.asf": asf.encode(),
                                                         "16_01.amc": amc_mutations[name].encode()},
                          ["build-graph", "{d}/16_01.amc", "-o", "{d}/g.npz"], "16_01.amc", outputs=("g.npz", "g.json")))
    cases.append(Case("amc", "no-asf-beside", {"16_01.amc": amc.encode()}, ["info", "{d}/16_01.amc"], "16_01.amc",
                      runner="mocap"))
    cases.append(Case("amc", "two-asf-beside", {"a.asf": asf.encode(), "b.asf": asf.encode(), "x.amc": amc.encode()},
                      ["info", "{d}/x.amc"], "x.amc", runner="mocap"))
    return cases


def c3d_cases() -> list[Case]:
    good = valid_c3d_bytes()
    n = len(good)
    params_start = 512  # the parameter section follows the 512-byte header block
    mutations = {
        "empty": b"",
        "text": b"not a c3d file\n" * 40,
        "header-only": good[:512],
        "cut-at-10pct": good[: n // 10],
        "cut-at-50pct": good[: n // 2],
        "cut-at-90pct": good[: n * 9 // 10],
        "cut-last-frame": good[: n - 600],
        "zero-parameters": good[:params_start] + bytes(n - params_start),
        "random-bytes": np.random.default_rng(1).integers(0, 256, n, dtype=np.uint8).tobytes(),
        "garbage-in-parameters": good[:params_start + 10] + bytes([0xFF]) * 300 + good[params_start + 310:],
        # implausible content (issue 22): nothing to label, coordinates no lab holds
        "all-nan": valid_c3d_bytes(change=lambda p: np.full_like(p, np.nan)),
        "coordinates-1e30": valid_c3d_bytes(change=lambda p: p * 1e30),
        "one-coordinate-2e6-m": valid_c3d_bytes(change=lambda p: np.where(np.arange(p.size).reshape(p.shape) == 7,
                                                                           2e6, p)),
    }
    cases = []
    for name, data in mutations.items():
        cases.append(Case("c3d", f"label-{name}", {"in.c3d": data}, ["label", "{d}/in.c3d", "-o", "{d}/out.c3d"],
                          "in.c3d", outputs=("out.c3d",)))
        cases.append(Case("c3d", f"fit-skeleton-{name}", {"in.c3d": data},
                          ["fit-skeleton", "{d}/in.c3d", "-o", "{d}/out.bvh"], "in.c3d", outputs=("out.bvh",)))
    cases.append(Case("c3d", "label-missing", {}, ["label", "{d}/in.c3d", "-o", "{d}/out.c3d"], "in.c3d",
                      outputs=("out.c3d",)))
    cases.append(Case("c3d", "label-too-few-frames", {"in.c3d": valid_c3d_bytes(frames=20)},
                      ["label", "{d}/in.c3d", "-o", "{d}/out.c3d"], "in.c3d", outputs=("out.c3d",)))
    cases.append(Case("c3d", "fit-skeleton-unknown-marker-set", {"in.c3d": good},
                      ["fit-skeleton", "{d}/in.c3d", "-o", "{d}/out.bvh"], "in.c3d", outputs=("out.bvh",)))
    return cases


def graph_cases(graph_path: Path, take: bytes) -> list[Case]:
    raw = graph_path.read_bytes()
    with np.load(graph_path) as z:
        arrays = {k: z[k] for k in z.files}
    header = json.loads(str(arrays["header_json"]))

    def with_(**changes) -> bytes:
        return _npz(**{**arrays, **changes})

    def without(*names) -> bytes:
        return _npz(**{k: v for k, v in arrays.items() if k not in names})

    mutations = {
        "empty": b"",
        "text": b"graph\n" * 10,
        "truncated-half": raw[: len(raw) // 2],
        "truncated-tail": raw[:-30],
        "zip-not-npz": _zip({"readme.txt": b"hello"}),
        "npz-no-header": without("header_json"),
        "header-not-json": with_(header_json=np.array("{not json")),
        "header-list": with_(header_json=np.array("[1, 2]")),
        "header-future-version": with_(header_json=np.array(json.dumps({**header, "format_version": 999}))),
        "missing-edges": without("edge_src", "edge_dst"),
        "edges-out-of-range": with_(edge_dst=arrays["edge_dst"] + 10_000),
        "edges-negative": with_(edge_src=arrays["edge_src"] - 1_000),
        "edges-float": with_(edge_src=arrays["edge_src"].astype(float) + 0.5),
        "edges-length-mismatch": with_(edge_dst=arrays["edge_dst"][:-3]),
        "positions-wrong-shape": with_(node_positions_m=arrays["node_positions_m"][:, :, :2]),
        "positions-nan": with_(node_positions_m=np.full_like(arrays["node_positions_m"], np.nan)),
        "meta-acc-nan": with_(meta_acc_g=np.full_like(arrays["meta_acc_g"], np.nan)),
        "rotations-wrong-shape": with_(node_rotations=arrays["node_rotations"][:, :, :3]),
        "nodes-fewer": with_(node_clip=arrays["node_clip"][:10]),
        "pickled-object": _npz(**{**arrays, "edge_src": np.array([None] * len(arrays["edge_src"]), dtype=object)}),
        "skeleton-parents-bad": with_(skeleton_parents=arrays["skeleton_parents"] + 100),
        "config-not-object": with_(header_json=np.array(json.dumps({**header, "config": "x"}))),
    }
    cases = []
    for name, data in mutations.items():
        cases.append(Case("graph", name, {"g.npz": data, "take.npz": take},
                          ["synthesize", "--graph", "{d}/g.npz", "--input", "{d}/take.npz", "-o", "{d}/out.bvh"],
                          "g.npz", outputs=("out.bvh",)))
    return cases


def _zip(files: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name, data in files.items():
            z.writestr(name, data)
    return buf.getvalue()


def take_cases(take: dict[str, np.ndarray]) -> list[Case]:
    acc, fps, pos = take["acc_g"], take["fps"], take["position_m"]
    acc_nan = acc.copy()
    acc_nan[len(acc) // 2, 0, 1] = np.nan
    acc_inf = acc.copy()
    acc_inf[3, 2, 0] = np.inf
    t = np.arange(len(acc)) / float(fps)
    export = {f"st1/{k}/acc_g": acc[:, k] for k in range(acc.shape[1])} | {f"st1/{k}/t_host_s": t for k in range(acc.shape[1])}
    quat = np.tile([1.0, 0.0, 0.0, 0.0], acc.shape[:2] + (1,))
    quat_scaled = quat.copy()
    quat_scaled[5, 1] *= 1.5  # not a unit quaternion
    quat_half_nan = quat.copy()
    quat_half_nan[7, 2, 1:] = np.nan
    mutations = {
        "empty": b"",
        "text": b"take\n" * 10,
        "truncated": _npz(**take)[:200],
        "npy-not-npz": _npy(acc),
        "pickled-array": _npz_pickled(**take),
        "pickle-file": pickle.dumps({"acc_g": acc}),
        "no-acc": _npz(fps=fps),
        "acc-2d": _npz(acc_g=acc[:, 0], fps=fps),
        "acc-4-axes": _npz(acc_g=np.concatenate([acc, acc[..., :1]], axis=2), fps=fps),
        "acc-strings": _npz(acc_g=acc.astype(str), fps=fps),
        "acc-complex": _npz(acc_g=acc.astype(complex), fps=fps),
        "acc-empty-T0": _npz(acc_g=acc[:0], fps=fps),
        "acc-one-sample": _npz(acc_g=acc[:1], fps=fps),
        "acc-one-nan": _npz(acc_g=acc_nan, fps=fps),
        "acc-all-nan": _npz(acc_g=np.full_like(acc, np.nan), fps=fps),
        "acc-inf": _npz(acc_g=acc_inf, fps=fps),
        "acc-too-many-sensors": _npz(acc_g=np.concatenate([acc, acc], axis=1), fps=fps),
        "fps-missing": _npz(acc_g=acc),
        "fps-zero": _npz(acc_g=acc, fps=0.0),
        "fps-negative": _npz(acc_g=acc, fps=-120.0),
        "fps-nan": _npz(acc_g=acc, fps=np.nan),
        "fps-inf": _npz(acc_g=acc, fps=np.inf),
        "fps-vector": _npz(acc_g=acc, fps=np.array([120.0, 60.0])),
        "fps-string": _npz(acc_g=acc, fps=np.array("fast")),
        "fps-tiny": _npz(acc_g=acc, fps=1e-9),
        "fps-huge": _npz(acc_g=acc, fps=1e12),
        "sensor-names-unknown": _npz(acc_g=acc, fps=fps, sensor_names=np.array(["a", "b", "c", "d", "e", "f"])),
        "sensor-names-count": _npz(acc_g=acc, fps=fps, sensor_names=np.array(["chest"])),
        "sensor-names-duplicate": _npz(acc_g=acc[:, :2], fps=fps, sensor_names=np.array(["chest", "chest"])),
        "position-wrong-shape": _npz(acc_g=acc, fps=fps, position_m=np.zeros((5, 7))),
        "position-3-columns": _npz(acc_g=acc, fps=fps, position_m=np.zeros((len(acc), 3))),
        "position-strings": _npz(acc_g=acc, fps=fps, position_m=pos.astype(str)),
        "heading-2d": _npz(acc_g=acc, fps=fps, heading_rad=np.zeros((len(acc), 2))),
        "heading-wrong-length": _npz(acc_g=acc, fps=fps, heading_rad=np.zeros(7)),
        "quat-wrong-shape": _npz(acc_g=acc, fps=fps, quat_wxyz=quat[..., :3]),
        "quat-not-unit": _npz(acc_g=acc, fps=fps, quat_wxyz=quat_scaled),
        "quat-row-half-nan": _npz(acc_g=acc, fps=fps, quat_wxyz=quat_half_nan),
        "gyro-wrong-length": _npz(acc_g=acc, fps=fps, gyro_rps=np.zeros((len(acc) - 1, acc.shape[1], 3))),
        "export-quat-not-unit": _npz(**export, **{"st1/1/quat_wxyz": quat_scaled[:, 1] * 2.0}),
        "export-gyro-2-axes": _npz(**export, **{"st1/0/gyro_rps": np.zeros((len(acc), 2))}),
        "export-missing-t": _npz(**{k: v for k, v in export.items() if not k.endswith("/t_host_s")}),
        "export-t-wrong-length": _npz(**{**export, "st1/0/t_host_s": t[:10]}),
        "export-t-backwards": _npz(**{**export, "st1/0/t_host_s": t[::-1].copy()}),
        "export-t-nan": _npz(**{**export, "st1/0/t_host_s": np.full_like(t, np.nan)}),
        "export-single-sample": _npz(**{k: v[:1] for k, v in export.items()}),
        "export-acc-2d": _npz(**{**export, "st1/0/acc_g": acc[:, 0, :2]}),
        "export-no-overlap": _npz(**{**export, "st1/1/t_host_s": t + 1000.0}),
        "export-messages-not-json": _npz(**export, messages=np.array("[{broken")),
        "export-messages-not-list": _npz(**export, messages=np.array('{"kind": "camera"}')),
        "export-camera-bad-position": _npz(**export, messages=np.array(json.dumps(
            [{"kind": "camera", "t_host_s": 0.1, "position_m": "here"}, {"kind": "camera", "t_host_s": 0.2,
                                                                         "position_m": [1, 2]}]))),
        "export-camera-no-time": _npz(**export, messages=np.array(json.dumps(
            [{"kind": "camera", "position_m": [0, 0]}, {"kind": "camera", "position_m": [1, 2]}]))),
    }
    cases = [Case("take", name, {"take.npz": data},
                  ["synthesize", "--graph", "{d}/g.npz", "--input", "{d}/take.npz", "-o", "{d}/out.bvh"],
                  "take.npz", outputs=("out.bvh",), shared={"g.npz": "graph"}) for name, data in mutations.items()]
    good = _npz(**take)
    for name, sensor_map in {"no-equals": ["st1/0"], "unknown-name": ["st1/0=elbow"], "empty-name": ["st1/0="],
                             "unknown-recorded": ["st9/9=chest"]}.items():
        data = good if name == "no-equals" else _npz(**export)
        cases.append(Case("take", f"sensor-map-{name}", {"take.npz": data},
                          ["synthesize", "--graph", "{d}/g.npz", "--input", "{d}/take.npz", "-o", "{d}/out.bvh",
                           "--sensor-map", *sensor_map], "--sensor-map", outputs=("out.bvh",),
                          shared={"g.npz": "graph"}))
    cases.append(Case("take", "longer-than-any-graph-path", {"take.npz": _npz(acc_g=np.concatenate([acc] * 6), fps=fps)},
                      ["synthesize", "--graph", "{d}/g.npz", "--input", "{d}/take.npz", "-o", "{d}/out.bvh"],
                      "g.npz", outputs=("out.bvh",), shared={"g.npz": "graph"}))
    for lag in ("-1", "nan", "inf"):
        cases.append(Case("take", f"lag-{lag}", {"take.npz": good},
                          ["synthesize", "--graph", "{d}/g.npz", "--input", "{d}/take.npz", "-o", "{d}/out.bvh",
                           "--lag", lag], "--lag", outputs=("out.bvh",), shared={"g.npz": "graph"}))
    for weights in (["nan", "1", "1"], ["-1", "1", "1"]):
        cases.append(Case("take", f"weights-{weights[0]}", {"take.npz": good},
                          ["synthesize", "--graph", "{d}/g.npz", "--input", "{d}/take.npz", "-o", "{d}/out.bvh",
                           "--weights", *weights], "--weights", outputs=("out.bvh",), shared={"g.npz": "graph"}))
    cases.append(Case("bvh", "build-graph-threshold-negative", {}, ["build-graph", "--sample", "--threshold", "-1", "-o",
                                                                   "{d}/g.npz"], "--threshold", outputs=("g.npz",)))
    cases.append(Case("bvh", "build-graph-no-clips", {}, ["build-graph", "--mocap-dir", "{d}/none", "-o", "{d}/g.npz"],
                      "no clips", outputs=("g.npz",)))
    cases.append(Case("take", "output-dir-missing", {"take.npz": good},
                      ["synthesize", "--graph", "{d}/g.npz", "--input", "{d}/take.npz", "-o", "{d}/no/such/out.bvh"],
                      "no/such", shared={"g.npz": "graph"}))
    return cases


def _npy(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, array)
    return buf.getvalue()


NESTED_JSON = b"[" * 100_000 + b"]" * 100_000


def record_with_entry(good: dict, **changes) -> bytes:
    """``good`` (a record's JSON document) with its first sensor entry's fields changed, as file bytes."""
    doc = json.loads(json.dumps(good))
    doc["sensors"][next(iter(doc["sensors"]))].update(changes)
    return json.dumps(doc).encode()


def calibration_cases() -> list[Case]:
    good = valid_calibration_record()
    sensor = next(iter(good["sensors"]))

    def entry(**changes) -> bytes:
        return record_with_entry(good, **changes)

    def top(**changes) -> bytes:
        return json.dumps({**good, **changes}).encode()

    mutations = {
        "empty": b"",
        "binary": bytes(range(256)),
        "not-json": b"{schema: courtside}",
        "json-list": b"[1, 2, 3]",
        "wrong-schema": top(schema="courtside.court_calibration"),
        "future-version": top(schema_version=7),
        "no-sensors": top(sensors={}),
        "sensors-list": top(sensors=[1, 2]),
        "entry-not-object": top(sensors={"a": 5}),
        "no-rotation": entry(rotation=None),
        "rotation-2x2": entry(rotation=[[1, 0], [0, 1]]),
        "rotation-not-orthonormal": entry(rotation=[[2, 0, 0], [0, 1, 0], [0, 0, 1]]),
        "rotation-reflection": entry(rotation=[[-1, 0, 0], [0, 1, 0], [0, 0, 1]]),
        "rotation-nan": entry(rotation=[[float("nan")] * 3] * 3),
        "rotation-strings": entry(rotation=[["a", "b", "c"]] * 3),
        "gravity-2": entry(gravity_sensor_g=[0, 1]),
        "norm-error-text": entry(norm_error_g="small"),
        "gravity-nan": entry(gravity_sensor_g=[0, float("nan"), 1]),
        "segment-duplicate": json.dumps({**good, "sensors": {**good["sensors"], "st9/9": good["sensors"][sensor]}}).encode(),
        "other-skeleton-frames": entry(rotation=[[1, 0, 0], [0, -1, 0], [0, 0, -1]], correction_deg=0.0),
        # issue 22: nested 100 000 deep (a RecursionError traceback), integers json cannot convert
        "nested-100000-deep": NESTED_JSON,
        "nested-in-a-field": top(sensors={}).replace(b'"sensors": {}', b'"sensors": ' + NESTED_JSON),
        "integer-5000-digits": top(schema_version=1).replace(b'"schema_version": 1', b'"schema_version": ' + b"7" * 5000),
        "segment-with-nul": entry(segment="che\x00st"),
    }
    return [Case("calibration", name, {"cal.json": data},
                 ["build-graph", "--sample", "--max-clips", "2", "--calibration", "{d}/cal.json", "-o", "{d}/g.npz"],
                 "cal.json", outputs=("g.npz", "g.json")) for name, data in mutations.items()]


def recording_cases() -> list[Case]:
    from gateway import codec

    meta = json.dumps({"take": "t"}).encode()
    samples = codec.encode("samples", {"station": "st1", "sensor": 0},
                           {"counter": np.arange(5, dtype=np.uint32), "t_host_s": np.arange(5) * 0.01,
                            "acc_g": np.zeros((5, 3), np.float32)})
    good = recording_bytes(meta, [samples] * 3)
    mutations = {
        "empty": b"",
        "text": b"hello, not a recording\n" * 5,
        "magic-only": b"CSREC\x00\x01\n",
        "header-truncated": good[:14],
        "header-length-huge": b"CSREC\x00\x01\n" + struct.pack(">I", 0xFFFFFFF0) + good[12:],
        "header-crc-bad-no-copy": good[:12] + b"{\"take\": \"u\"}"[: len(meta)] + good[12 + len(meta):],
        "header-json-invalid": recording_bytes(b'{"take": ', [samples]),
        "header-json-list": recording_bytes(b"[1, 2]", [samples]),
        "header-not-utf8": recording_bytes(b"\xff\xfe{}", [samples]),
        "chunk-no-station": recording_bytes(meta, [codec.encode("samples", {"sensor": 0}, {"counter": np.arange(3)})]),
        "chunk-sensor-text": recording_bytes(meta, [codec.encode("samples", {"station": "a", "sensor": "zero"},
                                                                 {"counter": np.arange(3)})]),
        "chunk-ragged": recording_bytes(meta, [codec.encode("samples", {"station": "a", "sensor": 0},
                                                            {"counter": np.arange(3), "acc_g": np.zeros((2, 3))})]),
        "chunk-scalar-array": recording_bytes(meta, [codec.encode("samples", {"station": "a", "sensor": 0},
                                                                  {"counter": np.array(3)})]),
        "chunks-disagree": recording_bytes(meta, [samples, codec.encode("samples", {"station": "st1", "sensor": 0},
                                                                        {"counter": np.arange(3)})]),
        "chunks-shape-disagree": recording_bytes(meta, [samples, codec.encode(
            "samples", {"station": "st1", "sensor": 0}, {"counter": np.arange(2, dtype=np.uint32),
                                                         "t_host_s": np.arange(2.0), "acc_g": np.zeros((2, 4), np.float32)})]),
        "chunk-body-not-codec": recording_bytes(meta, [b"\x00\x00\x00\x05hello"]),
        "chunk-body-bad-json": recording_bytes(meta, [struct.pack(">I", 5) + b"{bad}"]),
        "chunk-array-overruns": recording_bytes(meta, [samples[:-8]]),
        "chunk-json-nested-deep": recording_bytes(meta, [struct.pack(">I", 400_000) + b"[" * 200_000 + b"]" * 200_000]),
        "chunk-array-shape-huge": recording_bytes(meta, [_body({"kind": "samples", "station": "a", "sensor": 0, "arrays": [
            {"name": "c", "dtype": "<f8", "shape": [2**32, 2**32]}]})]),
        "clock-points-no-tick-hz": recording_bytes(meta, [codec.encode("clock_points", {"station": "a", "sensor": -1}, {
            "raw_ticks": np.arange(3, dtype=np.uint32), "ticks": np.arange(3), "epoch": np.zeros(3, np.uint32),
            "arrival_s": np.arange(3.0)})]),
    }
    cases = []
    for name, data in mutations.items():
        cases.append(Case("recording", name, {"take/take.csrec": data},
                          ["gateway", "export", "{d}/take", "--npz", "{d}/out.npz"], "take/take.csrec",
                          outputs=("out.npz", "out.npz.partial")))
    for name in ("header-json-invalid", "chunk-no-station"):
        cases.append(Case("recording", f"csv-{name}", {"take/take.csrec": mutations[name]},
                          ["gateway", "export", "{d}/take", "--csv-dir", "{d}/csv"], "take/take.csrec", outputs=("csv",)))
    cases.append(Case("recording", "missing-take", {}, ["gateway", "export", "{d}/take", "--npz", "{d}/out.npz"],
                      "take", outputs=("out.npz",)))
    cases.append(Case("recording", "export-to-missing-directory", {"take/take.csrec": good},
                      ["gateway", "export", "{d}/take", "--npz", "{d}/nowhere/out.npz"], "nowhere"))
    return cases


def camera_cases() -> list[Case]:
    schema = {"schema": "courtside.court_calibration", "schema_version": 1}
    court = {
        "empty": b"",
        "not-json": b"{",
        "json-list": b"[]",
        "wrong-schema": json.dumps({"schema": "x", "schema_version": 1}).encode(),
        "no-homography": json.dumps(schema).encode(),
        "homography-singular": json.dumps({**schema, "homography": [[0] * 3] * 3}).encode(),
        "homography-nan": json.dumps({**schema, "homography": [[float("nan")] * 3] * 3}).encode(),
        "homography-shape": json.dumps({**schema, "homography": [[1, 0], [0, 1]]}).encode(),
        "nested-100000-deep": NESTED_JSON,
        "nested-in-homography": json.dumps({**schema, "homography": 0}).encode().replace(b": 0}", b": " + NESTED_JSON + b"}"),
        "homography-strings": json.dumps({**schema, "homography": [["1", "0", "0"]] * 3}).encode(),
        "schema-version-object": json.dumps({**schema, "schema_version": {"v": 1}}).encode(),
    }
    cases = [Case("court-calibration", name, {"court.json": data},
                  ["camera", "track", "--video", "{d}/v.mp4", "--calibration", "{d}/court.json"], "court.json")
             for name, data in court.items()]
    clicks = {
        "empty": b"",
        "not-json": b"{near_baseline_left_doubles: [1, 2]}",
        "json-list": b"[[1, 2], [3, 4]]",
        "values-not-pairs": json.dumps({"near_baseline_left_doubles": 5, "net_left": [1, 2]}).encode(),
        "values-text": json.dumps({"near_baseline_left_doubles": ["a", "b"]}).encode(),
        "unknown-point": json.dumps({f"p{i}": [i, i * 2] for i in range(6)}).encode(),
        "too-few-points": json.dumps({"near_baseline_left_doubles": [1, 2]}).encode(),
        "nested-100000-deep": b"{\"net_left\": " + NESTED_JSON + b"}",
        "values-booleans": json.dumps({"near_baseline_left_doubles": [True, False]}).encode(),
    }
    cases += [Case("court-clicks", name, {"clicks.json": data},
                   ["camera", "calibrate", "--clicks", "{d}/clicks.json", "--image-size", "800", "450", "--out",
                    "{d}/court.json"], "clicks.json", outputs=("court.json",)) for name, data in clicks.items()]
    return cases


def config_cases() -> list[Case]:
    """The gateway's court config TOML (`courtside gateway --config`, gateway.court_config): the issue's cases
    (wrong types, a string where a list belongs, "no" as a boolean, negative counts, a table for a list)."""
    mutations = {
        "not-toml": b"listen = [\n",
        "binary": bytes(range(256)),
        "empty-key": b'= "x"\n',
        "unknown-key": b'portz = ["/dev/ttyACM0"]\n',
        "unknown-section": b'[cameras]\nsource = 0\n',
        "unknown-key-in-section": b'[stations]\nportz = ["/dev/ttyACM0"]\n',
        "emulate-text": b'[stations]\nemulate = "two"\n',
        "emulate-negative": b'[stations]\nemulate = -1\n',
        "emulate-float": b'[stations]\nemulate = 1.5\n',
        "ports-string": b'[stations]\nports = "/dev/ttyX"\n',
        "ports-table": b'[stations.ports]\na = "/dev/ttyX"\n',
        "ports-numbers": b'[stations]\nports = [1, 2]\n',
        "discover-no": b'[stations]\ndiscover = "no"\n',
        "listen-number": b"listen = 12\n",
        "listen-port-99999": b'listen = "127.0.0.1:99999"\n',
        "listen-no-port": b'listen = "localhost"\n',
        "record-dir-number": b"record_dir = 5\n",
        "record-take-dotdot": b'record = ".."\n',
        "max-clients-zero": b"max_clients = 0\n",
        "status-interval-negative": b"status_interval_s = -1.0\n",
        "stations-not-table": b'stations = "all"\n',
        "camera-side-bad": b'[camera]\nplayer_side = "middle"\n',
        "placements-unknown": b'[calibration]\nplacements = ["tail"]\n',
        "log-level-bad": b'log_level = "LOUD"\n',
        # issue 22: nesting, physical bounds, NUL bytes, non-string fields, one secret for two roles
        "nested-100000-deep": b"listen = " + b"[" * 100_000 + b"]" * 100_000 + b"\n",
        "integer-5000-digits": b"max_clients = " + b"7" * 5000 + b"\n",
        "handshake-timeout-1e-300": b"handshake_timeout_s = 1e-300\n",
        "status-interval-1e-9": b"status_interval_s = 1e-9\n",
        "camera-fps-tiny": b'[camera]\nfps = 1e-300\n',
        "record-dir-nul": b'record_dir = "rec\\u0000x"\n',
        "court-nul": b'[camera]\nsource = "v.mp4"\ncourt = "c\\u0000.json"\n',
        "ports-nul": b'[stations]\nports = ["/dev/tty\\u0000S0"]\n',
        "name-number": b"name = 5\n",
        "record-number": b"record = 7\n",
        "court-list": b'[camera]\ncourt = ["c.json"]\n',
        "secret-file-table": b'[auth.operator_secret_file]\npath = "s"\n',
        "placements-numbers": b'[calibration]\nplacements = [1, 2]\n',
        "same-secret-file": b'[auth]\noperator_secret_file = "s"\nviewer_secret_file = "s"\n',
        "missing-file": None,
    }
    cases = []
    for name, data in mutations.items():
        files = {} if data is None else {"gateway.toml": data}
        cases.append(Case("config", name, files, ["gateway", "--config", "{d}/gateway.toml", "--duration", "0",
                                                  "--quiet"], "gateway.toml"))
    cases.append(Case("config", "record-dir-is-a-file", {"gateway.toml": b'record_dir = "data"\n', "data": b"x"},
                      ["gateway", "--config", "{d}/gateway.toml", "--duration", "0", "--quiet"], "gateway.toml"))
    return cases


def knowledge_base_arrays() -> dict[str, np.ndarray]:
    """An OLNG knowledge base (`courtside reconstruct --save-kb`) over two short shipped clips, as arrays."""
    import tempfile

    from engine.olng.config import KnowledgeBaseConfig
    from engine.olng.mocap_bridge import build_knowledge_base

    clips = [load_clip(sample_clips()[name], fps=30.0).slice(0, 60) for name in ("16_01", "16_05")]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "kb.npz"
        build_knowledge_base(clips, KnowledgeBaseConfig(mirror=False, reverse=False)).save(path)
        with np.load(path) as z:
            return {k: z[k] for k in z.files}


def knowledge_base_cases(kb: dict[str, np.ndarray]) -> list[Case]:
    """`--kb` files that parse as .npz but hold the wrong arrays (the class that ended in IndexError, TypeError or
    ZeroDivisionError inside the OLNG before the load checked shapes, kinds and ranges)."""
    def with_(**changes) -> bytes:
        return _npz(**{**kb, **changes})

    mutations = {
        "empty": b"",
        "npy-not-npz": _npy(kb["alpha_g"]),
        "truncated": _npz(**kb)[:300],
        "no-alpha": _npz(**{k: v for k, v in kb.items() if k != "alpha_g"}),
        "alpha-1d": with_(alpha_g=kb["alpha_g"].ravel()),
        "alpha-nan": with_(alpha_g=np.full_like(kb["alpha_g"], np.nan)),
        "alpha-strings": with_(alpha_g=kb["alpha_g"].astype(str)),
        "fps-vector": with_(fps=np.array([25.0, 50.0])),
        "fps-zero": with_(fps=np.array(0.0)),
        "q-fewer-frames": with_(q=kb["q"][:3]),
        "names-fewer": with_(names=kb["names"][:2]),
        "parents-not-tree": with_(parents=np.arange(len(kb["parents"])) + 1),
        "sensor-bone-out-of-range": with_(sensor_bone=kb["sensor_bone"] + 1000),
        "clip-id-out-of-range": with_(clip_id=kb["clip_id"] + 5),
        "sensor-rot-2x2": with_(sensor_local_rot=kb["sensor_local_rot"][:, :2, :2]),
        "no-frames": with_(**{k: kb[k][:0] for k in ("q", "x_m", "v_mps", "a_mps2", "alpha_g", "clip_id",
                                                     "root_vel_heading_mps", "yaw_rate_rps", "root_height_m")}),
    }
    return [Case("knowledge-base", name, {"kb.npz": data, "take.npz": b"unused"},
                 ["reconstruct", "--method", "olng", "--kb", "{d}/kb.npz", "--input", "{d}/take.npz", "-o",
                  "{d}/out.bvh"], "kb.npz", outputs=("out.bvh",)) for name, data in mutations.items()]


def report_cases() -> list[Case]:
    """`courtside evaluate --compare` reports: JSON of another shape (the class that ended in KeyError/TypeError
    in the comparison table)."""
    row = {"engine": "motion graph", "sensors": "6", "camera": "yes", "global_cm": 9.0, "root_relative_cm": 8.0,
           "position_cm": 4.0, "heading_deg": 7.0}
    mutations = {
        "empty": b"",
        "not-json": b"{groups: 1}",
        "json-list": b"[1, 2]",
        "no-groups": json.dumps({"rows": [row]}).encode(),
        "groups-list": json.dumps({"groups": [row]}).encode(),
        "group-not-list": json.dumps({"groups": {"chained": row}}).encode(),
        "row-not-object": json.dumps({"groups": {"chained": [5]}}).encode(),
        "row-no-engine": json.dumps({"groups": {"chained": [{k: v for k, v in row.items() if k != "engine"}]}}).encode(),
        "value-text": json.dumps({"groups": {"chained": [{**row, "global_cm": "nine"}]}}).encode(),
    }
    good = json.dumps({"groups": {"chained": [row]}}).encode()
    return [Case("report", name, {"after.json": data, "before.json": good},
                 ["evaluate", "--compare", "{d}/before.json", "{d}/after.json"], "after.json")
            for name, data in mutations.items()]


def trace_cases() -> list[Case]:
    """`courtside emulate --trace` acceleration traces (.npy (F, S, 3) g)."""
    acc = np.zeros((20, 2, 3))
    acc[..., 1] = 1.0
    mutations = {
        "empty": b"",
        "text": b"0,1,0\n" * 5,
        "npz-not-npy": _npz(acc_g=acc),
        "pickled": pickle.dumps(acc),
        "truncated": _npy(acc)[:100],
        "two-axes": _npy(acc[..., :2]),
        "no-frames": _npy(acc[:0]),
        "nan": _npy(np.full_like(acc, np.nan)),
        "object-array": _npy(np.array([None, 1], dtype=object)),
    }
    return [Case("trace", name, {"trace.npy": data}, ["emulate", "--trace", "{d}/trace.npy", "--duration", "0.1"],
                 "trace.npy") for name, data in mutations.items()]
