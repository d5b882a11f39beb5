"""Every case of the generated malformed-input corpus through its real CLI: non-zero exit, exactly one stderr
line naming the file and the problem, no traceback, nothing half-written.

Cases run in-process through the same entry points the console scripts call (fast: ~200 cases); one case per
family also runs as a real subprocess, so interpreter-level behaviour (logging to stderr, exit status) is checked
as a user sees it."""
from __future__ import annotations

import contextlib
import io
import logging
import shutil
import subprocess
import sys
import traceback
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from . import corpus

SUBPROCESS_PREFIX = {
    "courtside": [sys.executable, "-m", "gateway.cli"],
    "mocap": [sys.executable, "-m", "engine.mocap"],
}


def _entry(runner: str):
    if runner == "courtside":
        from gateway.cli import main
    else:
        from engine.mocap.__main__ import main
    return main


@pytest.fixture(scope="session")
def shared(tmp_path_factory) -> dict[str, Path]:
    """Valid files several cases need: a small motion graph (two shipped clips, no transitions and no component
    step — `--no-connect` — so its longest path is ~5 s) and a synthesis input."""
    from engine.graph.cli import build_graph_main

    d = tmp_path_factory.mktemp("corpus-shared")
    clips = corpus.sample_clips()
    with contextlib.redirect_stdout(io.StringIO()):
        assert build_graph_main([str(clips["16_01"]), str(clips["16_05"]), "--no-connect", "-o", str(d / "g.npz")]) == 0
    np.savez(d / "take.npz", **corpus.take_arrays())
    return {"graph": d / "g.npz", "take": d / "take.npz"}


def _cases() -> list[corpus.Case]:
    """Every case but the graph ones, which need the shared graph's bytes (built in `test_malformed_graph`)."""
    return (corpus.bvh_cases() + corpus.asf_amc_cases() + corpus.c3d_cases() + corpus.calibration_cases()
            + corpus.take_cases(corpus.take_arrays()) + corpus.recording_cases() + corpus.camera_cases()
            + corpus.config_cases() + corpus.knowledge_base_cases(corpus.knowledge_base_arrays())
            + corpus.report_cases() + corpus.trace_cases())


CASES = _cases()
GRAPH_CASE_NAMES = ["empty", "text", "truncated-half", "truncated-tail", "zip-not-npz", "npz-no-header",
                    "header-not-json", "header-list", "header-future-version", "missing-edges", "edges-out-of-range",
                    "edges-negative", "edges-float", "edges-length-mismatch", "positions-wrong-shape",
                    "positions-nan", "meta-acc-nan", "rotations-wrong-shape", "nodes-fewer", "pickled-object",
                    "skeleton-parents-bad", "config-not-object"]


def _materialise(case: corpus.Case, d: Path, shared_paths: dict[str, Path]) -> list[str]:
    for rel, data in case.files.items():
        (d / rel).parent.mkdir(parents=True, exist_ok=True)
        (d / rel).write_bytes(data)
    for rel, key in case.shared.items():
        shutil.copy(shared_paths[key], d / rel)
    return [a.replace("{d}", str(d)) for a in case.argv]


def _run_in_process(case: corpus.Case, argv: list[str]) -> tuple[int, str, str | None]:
    err, out = io.StringIO(), io.StringIO()
    crash = None
    # what an unconfigured process does with warnings (logging.lastResort), which pytest's own handler would hide
    handler = logging.StreamHandler(err)
    handler.setLevel(logging.WARNING)
    logging.getLogger().addHandler(handler)
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = _entry(case.runner)(argv)
        except SystemExit as exc:  # what the interpreter does with it
            code = exc.code if isinstance(exc.code, int) else 1
            if isinstance(exc.code, str):
                print(exc.code, file=sys.stderr)
        except BaseException:  # noqa: BLE001 - this is exactly what must never happen
            code, crash = 1, traceback.format_exc()
        finally:
            logging.getLogger().removeHandler(handler)
    return int(code or 0), err.getvalue(), crash


def _check(case: corpus.Case, d: Path, code: int, stderr: str, crash: str | None) -> None:
    assert crash is None, f"{case.id}: traceback\n{crash}"
    assert "Traceback" not in stderr, f"{case.id}: traceback on stderr\n{stderr}"
    assert code != 0, f"{case.id}: exit 0 on a bad input (stderr {stderr!r})"
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1, f"{case.id}: expected one stderr line, got {lines}"
    named = case.bad if case.bad.startswith("--") or " " in case.bad else str(d / case.bad)
    assert named in lines[0], f"{case.id}: {lines[0]!r} does not name {named}"
    assert len(lines[0]) > len(named) + 12, f"{case.id}: {lines[0]!r} does not say what is wrong"
    for rel in case.outputs:
        assert not (d / rel).exists(), f"{case.id}: {rel} was left behind"


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_malformed_input(case, tmp_path, shared):
    argv = _materialise(case, tmp_path, shared)
    _check(case, tmp_path, *_run_in_process(case, argv))


@pytest.mark.parametrize("name", GRAPH_CASE_NAMES)
def test_malformed_graph(name, tmp_path, shared):
    case = next(c for c in corpus.graph_cases(shared["graph"], shared["take"].read_bytes()) if c.name == name)
    argv = _materialise(case, tmp_path, shared)
    _check(case, tmp_path, *_run_in_process(case, argv))


def test_graph_case_list_is_complete(shared):
    assert sorted(GRAPH_CASE_NAMES) == sorted(c.name for c in corpus.graph_cases(shared["graph"], b""))


def test_corpus_size_and_coverage(shared):
    """The counts quoted in the README's reliability section."""
    cases = CASES + corpus.graph_cases(shared["graph"], b"")
    files = sum(len(c.files) for c in cases)
    per_family = Counter(c.family for c in cases)
    assert len(cases) >= 150 and files >= 150
    assert set(per_family) >= {"bvh", "asf", "amc", "c3d", "graph", "take", "calibration", "recording", "config",
                               "knowledge-base", "report", "trace"}
    print(f"\nmalformed corpus: {len(cases)} cases, {files} files; " + ", ".join(f"{k} {v}" for k, v in
                                                                        sorted(per_family.items())))


def _one_per_family() -> list[corpus.Case]:
    seen: dict[str, corpus.Case] = {}
    for case in CASES:
        seen.setdefault(case.family, case)
    return list(seen.values())


@pytest.mark.parametrize("case", _one_per_family(), ids=lambda c: c.id)
def test_malformed_input_as_a_real_process(case, tmp_path, shared):
    argv = _materialise(case, tmp_path, shared)
    done = subprocess.run(SUBPROCESS_PREFIX[case.runner] + argv, capture_output=True, text=True, timeout=120,
                          cwd=Path(__file__).resolve().parents[2])
    _check(case, tmp_path, done.returncode, done.stderr, None)
