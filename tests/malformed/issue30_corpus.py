"""The issue-30 corpus: recordings that lost or invented data, crashed, or exhausted memory, as files.

Each case is a small device recording (generic CSV, Xsens MVNX, MT Manager text, an x-IMU3 logger folder) or a
take / calibration record, written from one synthetic two-sensor recording and then damaged in one way, with the
command that reads it and what must happen:

* `Refused`: exit 2, one stderr line naming the bad file once and saying ``says``;
* `Repaired`: exit 0, and ``check(case_dir)`` confirms the documented repair (a missing orientation stays NaN,
  never the identity; the other sensors keep theirs).

Every case also asserts that no file that existed before the command is changed (hash before/after)."""
from __future__ import annotations

import io
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from bench.support.imu_formats import Truth, write_generic_csv, write_mt_exports, write_mvnx, write_ximu3_logger
from engine.mocap import quaternions as quat

from .corpus import record_with_entry, valid_calibration_record

NAMES = ["left_forearm", "chest"]
FPS = 100.0
CSV_ARGS = ["--format", "csv", "--time", "time", "--time-unit", "ms"]


@dataclass
class Refused:
    name: str
    files: dict[str, bytes]  # path relative to the case directory -> content
    argv: list[str]  # "{d}" is the case directory
    bad: str  # relative path (or a literal such as "--rate") the one stderr line must name, once
    says: str  # a regular expression the line must match
    outputs: tuple[str, ...] = ("out.npz",)  # must not exist afterwards


@dataclass
class Repaired:
    name: str
    files: dict[str, bytes]
    argv: list[str]
    check: Callable[[Path], None]
    notes: list[str] = field(default_factory=list)  # regular expressions stderr must match (one line each)


# ------------------------------------------------------------------------------------------------ the base
def truth(seconds: float = 4.0) -> Truth:
    """Two sensors at rest for 1 s, then turning about changing axes (so w-first/w-last is decidable); specific
    force = gravity seen by the sensor (no translation), our world Y up."""
    t = np.arange(int(seconds * FPS)) / FPS
    moving = np.clip(t - 1.0, 0.0, None)
    rot = []
    for k in range(len(NAMES)):
        rotvec = np.stack([0.9 * np.sin(1.3 * moving + k), 0.7 * np.sin(0.8 * moving + 2 * k),
                           0.5 * np.sin(0.5 * moving)], axis=1)
        rot.append(quat.to_matrix(quat.from_rotvec(rotvec)))
    rot = np.stack(rot, axis=1)  # (F, S, 3, 3) sensor -> world
    acc = np.einsum("fsji,j->fsi", rot, np.array([0.0, 1.0, 0.0]))
    return Truth(acc, rot, np.zeros_like(acc), FPS, list(NAMES))


def _read(write: Callable[[Path], object], name: str) -> dict[str, bytes]:
    """Files a bench writer produces (in a temporary folder), relative to it."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        write(root / name)
        found = [root / name] if (root / name).is_file() else sorted(p for p in (root / name).rglob("*") if p.is_file())
        return {str(p.relative_to(root)): p.read_bytes() for p in found}


def csv_text() -> str:
    return _read(lambda p: write_generic_csv(p, truth(), "g", "wxyz", ",", "ms"), "rec.csv")["rec.csv"].decode()


def csv_columns() -> list[str]:
    cols = []
    for name in NAMES:
        cols += ["--sensor", f"{name}={name}_acc_x,{name}_acc_y,{name}_acc_z",
                 "--quat", f"{name}={name}_q0,{name}_q1,{name}_q2,{name}_q3"]
    return cols


def _rows(text: str) -> tuple[str, list[list[str]]]:
    header, *rows = text.strip().split("\n")
    return header, [r.split(",") for r in rows]


def _csv(text: str, change: Callable[[str, list[list[str]]], None]) -> bytes:
    """The CSV with ``change(header, rows)`` applied to its rows (lists of fields)."""
    header, rows = _rows(text)
    change(header, rows)
    return ("\n".join([header] + [",".join(r) for r in rows]) + "\n").encode()


def _col(header: str, name: str) -> int:
    return header.split(",").index(name)


def _set(column: str, rows_: slice | list[int], value: str | Callable[[str], str]):
    def change(header: str, rows: list[list[str]]) -> None:
        c = _col(header, column)
        for i in (range(len(rows))[rows_] if isinstance(rows_, slice) else rows_):
            rows[i][c] = value(rows[i][c]) if callable(value) else value
    return change


def _quat_rows(rows_: slice | list[int], values: list[str], sensor: str = "left_forearm"):
    def change(header: str, rows: list[list[str]]) -> None:
        for k, v in enumerate(values):
            _set(f"{sensor}_q{k}", rows_, v)(header, rows)
    return change


def _output(d: Path) -> dict[str, np.ndarray]:
    with np.load(d / "out.npz", allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _orientation_missing_not_invented(sensor: str, t_s: tuple[float, float]) -> Callable[[Path], None]:
    """The written take: ``sensor``'s orientation is NaN over ``t_s`` (not identity, not interpolated across),
    present elsewhere, and every orientation present is a unit quaternion."""
    def check(d: Path) -> None:
        take = _output(d)
        q = take["quat_wxyz"][:, list(take["sensor_names"]).index(sensor)]
        t = take["t_s"]  # every base recording starts at its first sample
        inside = (t >= t_s[0]) & (t <= t_s[1])
        assert np.isnan(q[inside]).all(), "a missing orientation was filled in"
        assert np.isfinite(q[~inside]).mean() > 0.9
        present = np.isfinite(q).all(axis=1)
        np.testing.assert_allclose(np.linalg.norm(q[present], axis=1), 1.0, atol=1e-6)
        assert np.isfinite(take["acc_g"]).all()
    return check


# ------------------------------------------------------------------------------------------------ families
def csv_cases() -> list[Refused]:
    text = csv_text()
    base = ["import-imu", "{d}/rec.csv", *CSV_ARGS, *csv_columns(), "-o", "{d}/out.npz"]

    def refused(name: str, change, says: str, argv: list[str] | None = None, bad: str = "rec.csv") -> Refused:
        return Refused(f"csv-{name}", {"rec.csv": _csv(text, change) if change else text.encode()}, argv or base,
                       bad, says)

    def with_(flag: str, value: str) -> list[str]:
        argv = list(base)
        i = argv.index(flag)
        argv[i + 1] = value
        return argv

    rate_argv = ["import-imu", "{d}/rec.csv", "--format", "csv", *csv_columns(), "-o", "{d}/out.npz", "--rate"]
    same_columns = [a.replace("chest_acc", "left_forearm_acc") if a.startswith("chest=chest_acc") else a
                    for a in base]
    return [
        refused("output-is-input", None, r"rec.csv: this output would overwrite the input file itself",
                with_("-o", "{d}/rec.csv")),
        refused("quaternion-inf", _quat_rows([50], ["inf", "0", "0", "0"]), r"line 52: .*infinite"),
        refused("quaternion-euler-angles", _quat_rows(slice(None), ["12.5", "-80.1", "33.0", "0"]),
                r"line 2: .*not a unit quaternion"),
        refused("quaternion-all-missing", _quat_rows(slice(None), ["", "", "", ""]), r"no orientation in any"),
        refused("quaternion-all-zero", _quat_rows(slice(None), ["0", "0", "0", "0"]), r"no orientation in any"),
        refused("acceleration-inf", _set("chest_acc_y", [120], "inf"), r"line 122: .*infinite"),
        refused("acceleration-1e300", _set("chest_acc_y", [120], "1e300"), r"line 122: .*beyond \+-1000 g"),
        refused("time-typo-1e10-ms-last-row", _set("time", [-1], "1e10"), r"would span .* h, more than the 6 h"),
        refused("time-typo-1e10-ms-mid-row", _set("time", [200], "1e10"),
                r"line 203: .*time goes back from 1e\+07 s to 2.01 s"),
        refused("time-clock-reset", _set("time", slice(250, None), lambda v: str(float(v) - 2400.0)),
                r"line 252: .*time goes back .*clock reset"),
        refused("time-hour-gap", _set("time", slice(250, None), lambda v: str(float(v) + 3.6e6)),
                r"line 252: .*no acceleration for 3600 s"),
        refused("time-not-a-number", _set("time", [9], "nan"), r"line 11: .*time nan is not a number"),
        refused("time-unit-wrong-100-khz", None, r"sample rate 100000 Hz is outside 1..4000 Hz.*--time-unit",
                with_("--time-unit", "us")),
        refused("rate-negative", None, r"--rate -100 Hz is outside 1..4000 Hz", rate_argv + ["-100"], "--rate"),
        refused("rate-tiny", None, r"--rate 1e-09 Hz is outside", rate_argv + ["1e-9"], "--rate"),
        refused("rate-1e12", None, r"--rate 1e\+12 Hz is outside", rate_argv + ["1e12"], "--rate"),
        refused("output-directory-missing", None, r"out.npz: output directory .*/no does not exist",
                with_("-o", "{d}/no/out.npz"), "no/out.npz"),
        refused("two-placements-same-columns", None, r"line 1: column 'left_forearm_acc_x' is mapped twice",
                same_columns),
    ]


def csv_repairs() -> list[Repaired]:
    text = csv_text()
    argv = ["import-imu", "{d}/rec.csv", *CSV_ARGS, *csv_columns(), "-o", "{d}/out.npz"]
    return [
        Repaired("csv-quaternion-nan-rows", {"rec.csv": _csv(text, _quat_rows(slice(150, 160), ["nan"] * 4))}, argv,
                 _orientation_missing_not_invented("left_forearm", (1.505, 1.585))),
        Repaired("csv-quaternion-zero-rows", {"rec.csv": _csv(text, _quat_rows(slice(150, 160), ["0"] * 4))}, argv,
                 _orientation_missing_not_invented("left_forearm", (1.505, 1.585))),
    ]


def mvnx_text() -> str:
    return _read(lambda p: write_mvnx(p, truth()), "rec.mvnx")["rec.mvnx"].decode()


def _mvnx_orientation(text: str, frames: range | None, sensor: int, values: str) -> str:
    """``values`` as sensor ``sensor``'s orientation in the normal frames ``frames`` (None: all)."""
    pattern = re.compile(r'(<frame time="(\d+)" index="(\d+)"[^>]*>.*?<sensorOrientation>)([^<]*)</sensorOrientation>')

    def per_frame(m: re.Match) -> str:
        if frames is not None and int(m.group(3)) not in frames:
            return m.group(0)
        numbers = m.group(4).split()
        numbers[4 * sensor:4 * sensor + 4] = values.split()
        return f"{m.group(1)}{' '.join(numbers)}</sensorOrientation>"

    return pattern.sub(per_frame, text)


def mvnx_cases() -> tuple[list[Refused], list[Repaired]]:
    text = mvnx_text()
    argv = ["import-imu", "{d}/rec.mvnx", "--format", "xsens", "-o", "{d}/out.npz"]
    empty = re.sub(r"<sensorOrientation>[^<]*</sensorOrientation>", "<sensorOrientation/>", text, count=1)
    entity = text.replace('<mvnx version', '<!DOCTYPE mvnx [<!ENTITY q "0.5 0.5 0.5 0.5">]>\n<mvnx version', 1)
    refused = [
        Refused("mvnx-empty-sensor-orientation", {"rec.mvnx": empty.encode()}, argv, "rec.mvnx",
                r"frame '0': sensorOrientation holds 0 numbers, expected 12"),
        Refused("mvnx-orientation-all-zero", {"rec.mvnx": _mvnx_orientation(text, None, 0, "0 0 0 0").encode()},
                argv, "rec.mvnx", r"sensor 'LeftForeArm': no orientation in any"),
        Refused("mvnx-orientation-not-unit", {"rec.mvnx": _mvnx_orientation(text, range(5, 6), 1, "2 0 0 0")
                                              .encode()}, argv, "rec.mvnx", r"sample 5: .*not a unit quaternion"),
        Refused("mvnx-orientation-missing-for-1-s", {"rec.mvnx": _mvnx_orientation(text, range(150, 250), 0,
                                                                                   "nan nan nan nan").encode()},
                argv, "rec.mvnx", r"no acceleration for 1.01 s"),
        Refused("mvnx-entity-declaration", {"rec.mvnx": entity.encode()}, argv, "rec.mvnx", r"line 2: a DOCTYPE"),
        Refused("mvnx-entity-declaration-after-a-comment", {"rec.mvnx": entity.replace(
            "<!DOCTYPE", "<!-- <mvnx> " + "x" * 70_000 + " -->\n<!DOCTYPE", 1).encode()}, argv, "rec.mvnx",
            r"line 3: a DOCTYPE"),
    ]
    repaired = [
        Repaired("mvnx-orientation-nan-frames", {"rec.mvnx": _mvnx_orientation(text, range(150, 160), 0,
                                                                              "nan nan nan nan").encode()}, argv,
                 _orientation_missing_not_invented("left_forearm", (1.505, 1.585)),
                 [r"not mapped to a placement, left out: Head"]),
    ]
    return refused, repaired


def mt_files() -> dict[str, bytes]:
    return _read(lambda p: write_mt_exports(p, truth(), ["00B40001"]), "mt")


def _mt(change: Callable[[list[str]], list[str]]) -> dict[str, bytes]:
    (name, data), = mt_files().items()
    return {name: ("\n".join(change(data.decode().strip().split("\n"))) + "\n").encode()}


def _mt_without_sample_time(update_rate: str) -> Callable[[list[str]], list[str]]:
    def change(lines: list[str]) -> list[str]:
        out = []
        for line in lines:
            if line.startswith("//"):
                out.append(line)
                if "DeviceId" in line:
                    out.append(f"//  Update Rate: {update_rate}")
            else:
                fields = line.split("\t")
                out.append("\t".join(fields[:1] + fields[2:]))
        return out
    return change


def _mt_quat(rows: range, values: list[str]) -> Callable[[list[str]], list[str]]:
    def change(lines: list[str]) -> list[str]:
        first = next(i for i, line in enumerate(lines) if not line.startswith("//")) + 1
        for i in rows:
            fields = lines[first + i].split("\t")
            fields[-4:] = values
            lines[first + i] = "\t".join(fields)
        return lines
    return change


def mt_cases() -> tuple[list[Refused], list[Repaired]]:
    name = next(iter(mt_files()))
    argv = ["import-imu", "{d}/" + name, "--format", "xsens", "--sensor-map", "00B40001=chest", "-o", "{d}/out.npz"]
    refused = [
        Refused("mt-update-rate-fast", _mt(_mt_without_sample_time("fast")), argv, name,
                r"line 6: Update Rate 'fast' is not a sample rate"),
        Refused("mt-update-rate-1.0.0Hz", _mt(_mt_without_sample_time("1.0.0Hz")), argv, name,
                r"line 6: Update Rate '1.0.0Hz' is not a sample rate"),
        Refused("mt-update-rate-1e9Hz", _mt(_mt_without_sample_time("1000000000Hz")), argv, name,
                r"line 6: Update Rate '1000000000Hz' is not a sample rate \(.* outside 1..4000 Hz\)"),
        Refused("mt-euler-angles-in-quaternion-columns", _mt(_mt_quat(range(400), ["12.0", "-3.5", "87.0", "0"])),
                argv, name, r"line 14: .*not a unit quaternion"),
    ]
    repaired = [
        Repaired("mt-quaternion-zero-rows", _mt(_mt_quat(range(150, 160), ["0"] * 4)), argv,
                 _orientation_missing_not_invented("chest", (1.505, 1.585))),
    ]
    return refused, repaired


def ximu3_files() -> dict[str, bytes]:
    return _read(lambda p: write_ximu3_logger(p, truth(), ["0000A001", "0000A002"], ["Left Forearm", "Chest"],
                                              [1_000_000, 5_000_000]), "rec")


def _ximu3(change: Callable[[dict[str, bytes]], None]) -> dict[str, bytes]:
    files = ximu3_files()
    change(files)
    return files


def ximu3_cases() -> tuple[list[Refused], list[Repaired]]:
    argv = ["import-imu", "{d}/rec", "--format", "ximu3", "-o", "{d}/out.npz"]
    forearm_q = "rec/Left Forearm 0000A001 (USB)/Quaternion.csv"
    forearm_i = "rec/Left Forearm 0000A001 (USB)/Inertial.csv"

    def keep_rows(path: str, rows: slice):
        def change(files: dict[str, bytes]) -> None:
            header, *lines = files[path].decode().strip().split("\n")
            files[path] = ("\n".join([header] + lines[rows]) + "\n").encode()
        return change

    def shift_clock(path: str, by_us: int, from_row: int = 0):
        def change(files: dict[str, bytes]) -> None:
            header, *lines = files[path].decode().strip().split("\n")
            for i in range(from_row, len(lines)):
                t, rest = lines[i].split(",", 1)
                lines[i] = f"{int(t) + by_us},{rest}"
            files[path] = ("\n".join([header] + lines) + "\n").encode()
        return change

    def drop(path: str):
        return lambda files: files.pop(path)

    no_inertial = _ximu3(drop(forearm_i))
    refused = [
        Refused("ximu3-mapped-device-without-inertial", no_inertial, argv, "rec/Left Forearm 0000A001 (USB)",
                r"mapped to 'left_forearm' but holds no Inertial.csv"),
        Refused("ximu3-quaternion-no-rows", _ximu3(keep_rows(forearm_q, slice(0, 0))), argv, forearm_q,
                r"a header but no data rows"),
        Refused("ximu3-quaternion-one-row", _ximu3(keep_rows(forearm_q, slice(0, 1))), argv, forearm_q,
                r"its 1 orientation row\(s\) .* do not cover Inertial.csv"),
        Refused("ximu3-quaternion-other-clock", _ximu3(shift_clock(forearm_q, 10**9)), argv, forearm_q,
                r"do not cover Inertial.csv.*another clock"),
        Refused("ximu3-quaternion-all-zero", _ximu3(lambda f: f.update({forearm_q: re.sub(
            rb"\n(\d+),[^\n]*", rb"\n\1,0,0,0,0", f[forearm_q])})), argv, forearm_q, r"no orientation in any"),
        Refused("ximu3-device-clock-reset", _ximu3(shift_clock(forearm_i, -1_000_000, 200)), argv, forearm_i,
                r"line 202: .*time goes back .*clock reset"),
    ]
    repaired = [
        Repaired("ximu3-one-device-without-quaternion", _ximu3(drop(forearm_q)), argv, _others_keep_orientation,
                 [r"no orientation from Left Forearm 0000A001 \(USB\)"]),
    ]
    return refused, repaired


def _others_keep_orientation(d: Path) -> None:
    take = _output(d)
    names = list(take["sensor_names"])
    q = take["quat_wxyz"]
    assert np.isnan(q[:, names.index("left_forearm")]).all()
    # the chest keeps its orientation (NaN only after its last Quaternion.csv row: never extrapolated)
    assert np.isfinite(q[:-1, names.index("chest")]).all()


# ------------------------------------------------------------------------------------------------ takes
def take_arrays() -> dict[str, np.ndarray]:
    tr = truth()
    q = quat.from_matrix(tr.rot)
    return {"acc_g": tr.acc_g, "fps": np.array(FPS), "sensor_names": np.array(NAMES),
            "source_labels": np.array(["dev-a", "dev-b"]), "quat_wxyz": q}


def _npz(**arrays) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def take_cases() -> list[Refused]:
    """Bad takes, refused alike by calibrate and synthesize (the shared take check); synthesize needs the
    shared graph (``{graph}``)."""
    good = take_arrays()
    acc = good["acc_g"]

    def with_(**changes) -> bytes:
        return _npz(**{**good, **changes})

    big = acc.copy()
    big[7, 1, 2] = 1e300
    mutations = {
        "zero-length": (with_(acc_g=acc[:0], quat_wxyz=good["quat_wxyz"][:0]), r"at least 2 samples"),
        "short-source-labels": (with_(source_labels=np.array(["dev-a"])), r"source_labels has 1 entries"),
        "duplicate-source-labels": (with_(source_labels=np.array(["dev-a", "dev-a"])), r"name a sensor twice"),
        "fps-inf": (with_(fps=np.array(np.inf)), r"'fps' = inf Hz is outside 1..4000 Hz"),
        "fps-array": (with_(fps=np.array([100.0, 100.0])), r"'fps' must be one number"),
        "fps-string": (with_(fps=np.array("fast")), r"'fps' must be real numbers"),
        "fps-100-khz": (with_(fps=np.array(1e5)), r"outside 1..4000 Hz"),
        "object-array": (with_(acc_g=np.array([[None]], dtype=object)), r"'acc_g' holds Python objects"),
        "acceleration-1e300": (with_(acc_g=big), r"beyond \+-1000 g"),
        "quaternions-all-zero": (with_(quat_wxyz=np.zeros_like(good["quat_wxyz"])), r"not unit length"),
    }
    out = []
    for name, (data, says) in mutations.items():
        out.append(Refused(f"calibrate-{name}", {"take.npz": data}, ["calibrate", "{d}/take.npz", "-o",
                                                                      "{d}/take.calibration.json"],
                           "take.npz", says, ("take.calibration.json", "take.calibration.npz")))
        out.append(Refused(f"synthesize-{name}", {"take.npz": data}, ["synthesize", "--graph", "{graph}", "--input",
                                                                       "{d}/take.npz", "-o", "{d}/out.bvh"],
                           "take.npz", says, ("out.bvh",)))
    t = np.arange(len(acc)) / FPS
    export = _npz(**{f"st1/{k}/acc_g": big[:, k] for k in range(len(NAMES))},
                  **{f"st1/{k}/t_host_s": t for k in range(len(NAMES))})
    sensor_map = ["--sensor-map", *(f"st1/{k}={name}" for k, name in enumerate(NAMES))]
    out += [
        Refused("calibrate-export-acceleration-1e300", {"rec.npz": export}, ["calibrate", "{d}/rec.npz", *sensor_map,
                                                                             "-o", "{d}/rec.calibration.json"],
                "rec.npz", r"st1/1/acc_g holds values beyond \+-1000 g", ("rec.calibration.json",)),
        Refused("synthesize-export-acceleration-1e300", {"rec.npz": export}, ["synthesize", "--graph", "{graph}",
                                                                              "--input", "{d}/rec.npz", "-o",
                                                                              "{d}/out.bvh"],
                "rec.npz", r"st1/1/acc_g holds values beyond \+-1000 g", ("out.bvh",)),
        Refused("calibrate-output-directory-missing", {"t.npz": _npz(**good)}, ["calibrate", "{d}/t.npz", "-o",
                                                                               "{d}/no/t.calibration.json"],
                "no/t.calibration.json", r"output directory .*/no does not exist", ()),
        Refused("calibrate-output-over-its-take", {"t.npz": _npz(**good)}, ["calibrate", "{d}/t.npz", "-o",
                                                                           "{d}/t.json"], "t.npz",
                r"t.npz: the raw samples of -o .*t.json would overwrite the input file itself", ("t.json",)),
        Refused("synthesize-output-over-its-take", {"t.npz": _npz(**good)}, ["synthesize", "--graph", "{graph}",
                                                                            "--input", "{d}/t.npz", "-o", "{d}/t.npz"],
                "t.npz", r"t.npz: this output would overwrite the input file itself", ()),
        Refused("synthesize-poses-over-its-take", {"t.npz": _npz(**good)}, ["synthesize", "--graph", "{graph}",
                                                                           "--input", "{d}/t.npz", "-o", "{d}/o.bvh",
                                                                           "--save-poses", "{d}/./t.npz"],
                "t.npz", r"this output would overwrite the input file itself", ("o.bvh",)),
        Refused("synthesize-folder-as-take", {"rec/Inertial.csv": b"x"}, ["synthesize", "--graph", "{graph}",
                                                                          "--input", "{d}/rec", "-o", "{d}/out.bvh"],
                "rec", r"rec: a folder, not a take .npz; a device recording .* `courtside import-imu`$", ("out.bvh",)),
        Refused("synthesize-csv-as-take", {"rec.csv": csv_text().encode()}, ["synthesize", "--graph", "{graph}",
                                                                              "--input", "{d}/rec.csv", "-o",
                                                                              "{d}/out.bvh"],
                "rec.csv", r"rec.csv: not an .npz archive \(not a zip of numpy arrays\); a device recording",
                ("out.bvh",)),
        Refused("synthesize-text-named-npz", {"take.npz": b"acc_g,fps\n1,2\n"}, ["synthesize", "--graph", "{graph}",
                                                                                  "--input", "{d}/take.npz", "-o",
                                                                                  "{d}/out.bvh"],
                "take.npz", r"take.npz: not an .npz archive \(not a zip of numpy arrays\)$", ("out.bvh",)),
    ]
    return out


# ------------------------------------------------------------------------------------------------ records
def record_cases() -> list[Refused]:
    good = valid_calibration_record()
    sensor = next(iter(good["sensors"]))

    def entry(**changes) -> bytes:
        return record_with_entry(good, **changes)

    many = {f"st/{i}": {**good["sensors"][sensor], "segment": f"s{i}"} for i in range(100_000)}
    unknown = {sid: {**s, "segment": f"tail_{i}"} for i, (sid, s) in enumerate(good["sensors"].items())}
    mutations = {
        "passed-no": (entry(passed="no"), r"'passed' must be true or false, got 'no'"),
        "record-passed-no": (json.dumps({**good, "passed": "no"}).encode(), r"'passed' must be true or false"),
        "yaw-1e300": (entry(orientation_yaw_rad=1e300, orientation_mount_wxyz=[1, 0, 0, 0]),
                      r"is not an angle in \[-2 pi, 2 pi\]"),
        "only-unknown-segments": (json.dumps({**good, "sensors": unknown}).encode(), r"no sensor on a known segment"),
        "100000-sensors": (json.dumps({**good, "sensors": many}).encode(), r"100000 sensors: more than the 64"),
    }
    return [Refused(f"record-{name}", {"cal.json": data},
                    ["build-graph", "--sample", "--max-clips", "2", "--calibration", "{d}/cal.json", "-o",
                     "{d}/g.npz"], "cal.json", says, ("g.npz", "g.json"))
            for name, (data, says) in mutations.items()]


def refused_cases() -> list[Refused]:
    mvnx, mt, ximu3 = mvnx_cases(), mt_cases(), ximu3_cases()
    return csv_cases() + mvnx[0] + mt[0] + ximu3[0] + take_cases() + record_cases()


def repaired_cases() -> list[Repaired]:
    return csv_repairs() + mvnx_cases()[1] + mt_cases()[1] + ximu3_cases()[1]
