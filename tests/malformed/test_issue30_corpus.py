"""Issue 30's corpus through the real `courtside` entry point (`issue30_corpus`): each refused case exits 2 with
one stderr line naming the bad file once and saying what is wrong (no traceback, nothing half-written); each
repaired case exits 0 with the documented repair in its output; and no case changes a file that existed before
the command ran (inputs are never modified, even when -o names one of them)."""
from __future__ import annotations

import contextlib
import hashlib
import io
import re
import traceback
from pathlib import Path

import numpy as np
import pytest

from . import issue30_corpus as corpus

REFUSED = corpus.refused_cases()
REPAIRED = corpus.repaired_cases()


@pytest.fixture(scope="module")
def graph(tmp_path_factory) -> Path:
    """A small motion graph (two shipped clips, --no-connect), for the synthesize cases."""
    from engine.graph.cli import build_graph_main
    from engine.mocap import sample_clips

    path = tmp_path_factory.mktemp("issue30-graph") / "g.npz"
    clips = sample_clips()
    with contextlib.redirect_stdout(io.StringIO()):
        assert build_graph_main([str(clips["16_01"]), str(clips["16_05"]), "--no-connect", "-o", str(path)]) == 0
    return path


def _materialise(files: dict[str, bytes], argv: list[str], d: Path, graph_path: Path | None) -> list[str]:
    for rel, data in files.items():
        (d / rel).parent.mkdir(parents=True, exist_ok=True)
        (d / rel).write_bytes(data)
    return [a.replace("{d}", str(d)).replace("{graph}", str(graph_path)) for a in argv]


def _hashes(d: Path) -> dict[Path, str]:
    return {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in d.rglob("*") if p.is_file()}


def _run(argv: list[str]) -> tuple[int, list[str], str | None]:
    """(exit status, non-empty stderr lines, traceback of anything escaping the dispatcher)."""
    from gateway.cli import main

    err = io.StringIO()
    crash = None
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except BaseException:  # noqa: BLE001 - exactly what must never happen
            code, crash = 1, traceback.format_exc()
    return int(code or 0), [line for line in err.getvalue().splitlines() if line.strip()], crash


def _needs_graph(argv: list[str]) -> bool:
    return any("{graph}" in a for a in argv)


@pytest.mark.parametrize("case", REFUSED, ids=[c.name for c in REFUSED])
def test_refused_with_one_line_naming_the_file_once(case, tmp_path, request):
    graph_path = request.getfixturevalue("graph") if _needs_graph(case.argv) else None
    argv = _materialise(case.files, case.argv, tmp_path, graph_path)
    before = _hashes(tmp_path)
    code, lines, crash = _run(argv)
    assert crash is None, crash
    assert code == 2 and len(lines) == 1, (code, lines)
    named = case.bad if case.bad.startswith("--") else str(tmp_path / case.bad)
    assert lines[0].count(named) == 1, f"{lines[0]!r} should name {named} exactly once"
    assert re.search(case.says, lines[0]), f"{lines[0]!r} does not say {case.says!r}"
    assert "allow_pickle" not in lines[0] and "Traceback" not in lines[0]
    assert _hashes(tmp_path) == before, "a refused command changed or left files"
    for rel in case.outputs:
        assert not (tmp_path / rel).exists()


@pytest.mark.parametrize("case", REPAIRED, ids=[c.name for c in REPAIRED])
def test_repaired_without_inventing_data(case, tmp_path):
    argv = _materialise(case.files, case.argv, tmp_path, None)
    before = _hashes(tmp_path)
    code, lines, crash = _run(argv)
    assert crash is None, crash
    assert code == 0, lines
    assert len(lines) == len(case.notes) and all(re.search(n, line) for n, line in zip(case.notes, lines)), lines
    after = _hashes(tmp_path)
    assert {p: after[p] for p in before} == before, "an input file was changed"
    case.check(tmp_path)


def test_no_command_modifies_its_inputs(tmp_path):
    """A whole valid chain (import-imu on each format, then calibrate the take): every file that existed before a
    command keeps its bytes, and an output named like an input is refused (the take survives
    ``calibrate a.npz -o a.json``, whose raw samples would go to a.npz)."""
    files = {"rec.csv": corpus.csv_text().encode(), **corpus.ximu3_files(), **corpus.mt_files(),
             "rec.mvnx": corpus.mvnx_text().encode()}
    mt = next(k for k in files if k.startswith("mt/"))
    runs = [(0, ["import-imu", "{d}/rec.csv", *corpus.CSV_ARGS, *corpus.csv_columns(), "-o", "{d}/a.npz"]),
            (0, ["import-imu", "{d}/rec", "--format", "ximu3", "-o", "{d}/b.npz"]),
            (0, ["import-imu", "{d}/" + mt, "--format", "xsens", "--sensor-map", "00B40001=chest", "-o", "{d}/c.npz"]),
            (0, ["import-imu", "{d}/rec.mvnx", "--format", "xsens", "-o", "{d}/d.npz"]),
            (0, ["calibrate", "{d}/a.npz", "-o", "{d}/a.calibration.json"]),
            (2, ["calibrate", "{d}/a.npz", "-o", "{d}/a.json"]),
            (2, ["import-imu", "{d}/rec", "--format", "ximu3", "-o", "{d}/rec/Chest 0000A002 (USB)/Inertial.csv"])]
    _materialise(files, [], tmp_path, None)
    for status, argv in runs:
        before = _hashes(tmp_path)
        code, lines, crash = _run(_materialise({}, argv, tmp_path, None))
        assert crash is None and code == status, (argv, code, lines)
        after = _hashes(tmp_path)
        assert {p: after[p] for p in before} == before, argv
    for name in "abcd":
        with np.load(tmp_path / f"{name}.npz") as take:
            assert np.isfinite(take["acc_g"]).all()
            assert np.isfinite(take["quat_wxyz"]).all(axis=-1).mean() > 0.99  # orientations kept, none invented


def test_corpus_size():
    """The count quoted in docs/imu-import.md."""
    assert len(REFUSED) + len(REPAIRED) >= 60
    print(f"\nissue-30 corpus: {len(REFUSED)} refused, {len(REPAIRED)} repaired")


@pytest.mark.parametrize("argv", [
    ["build-graph", "{d}/clip.bvh", "-o", "{d}/clip.bvh"],
    ["build-graph", "{d}/clip.bvh", "-o", "{d}/clip.npz"],  # beside its input: refused only for the bad clip
    ["label", "{d}/m.c3d", "-o", "{d}/./m.c3d"],
    ["fit-skeleton", "{d}/m.c3d", "-o", "{d}/m.c3d"],
    ["reconstruct", "--method", "hmm", "--input", "{d}/t.npz", "-o", "{d}/t.npz"],
])
def test_no_command_writes_over_its_input(tmp_path, argv, capsys):
    """Every command that writes a file refuses an output naming one of its inputs, before reading anything
    (the input is left byte for byte), naming the file; an output beside the inputs is not refused."""
    from gateway.cli import main as courtside

    inputs = {"clip.bvh": b"HIERARCHY\n", "m.c3d": b"\0" * 512, "t.npz": b"PK\x03\x04"}
    for name, data in inputs.items():
        (tmp_path / name).write_bytes(data)
    argv = [a.replace("{d}", str(tmp_path)) for a in argv]
    before = {n: hashlib.sha256((tmp_path / n).read_bytes()).hexdigest() for n in inputs}
    code = courtside(argv)
    err = capsys.readouterr().err
    assert {n: hashlib.sha256((tmp_path / n).read_bytes()).hexdigest() for n in inputs} == before
    assert code == 2
    if argv[-1].endswith("clip.npz"):  # refused for the bad clip, not for the output
        assert "overwrite" not in err
    else:
        assert "would overwrite the input file itself" in err and err.count("\n") == 1
