"""One CLI error style: every `courtside` subcommand (each ``courtside.commands`` entry point), given a bad
argument or a bad file, exits 2 with exactly one line on stderr and no traceback.

The list of subcommands comes from the installed entry points, so a new subcommand without a bad-file case
below fails here (``demo`` reads no input file: it is checked with a bad argument only)."""
from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

from gateway.cli import available_commands, main as courtside

GARBAGE = b"\x00\x01 not what this command reads \xff\xfe\n" * 3

# subcommand -> argv with "{bad}" where the garbage file goes (its name ends as the command expects)
BAD_FILE: dict[str, tuple[str, list[str]]] = {
    "emulate": ("trace.npy", ["--trace", "{bad}", "--duration", "0.1"]),
    "gateway": ("court.toml", ["--config", "{bad}", "--duration", "0", "--quiet"]),
    "camera": ("court.json", ["track", "--video", "{d}/v.mp4", "--calibration", "{bad}"]),
    "console": ("cal.calibration.json", ["--calibration", "{bad}", "--playback", "{d}/take"]),
    "build-graph": ("clip.bvh", ["{bad}", "-o", "{d}/g.npz"]),
    "synthesize": ("g.npz", ["--graph", "{bad}", "--input", "{bad}", "-o", "{d}/out.bvh"]),
    "evaluate": ("report.json", ["--protocol", "chained", "--compare", "{bad}", "{bad}"]),
    "graph-info": ("g.npz", ["{bad}"]),
    "reconstruct": ("kb.npz", ["--method", "olng", "--kb", "{bad}", "--input", "{bad}", "-o", "{d}/out.bvh"]),
    "label": ("markers.c3d", ["{bad}", "-o", "{d}/out.c3d"]),
    "fit-skeleton": ("markers.c3d", ["{bad}", "-o", "{d}/out.bvh"]),
    "import-imu": ("device.csv", ["{bad}", "--format", "csv", "--sensor", "chest=ax,ay,az", "--rate", "100",
                                  "-o", "{d}/take.npz"]),
    "calibrate": ("take.npz", ["{bad}", "-o", "{d}/take.calibration.json"]),
}
NO_INPUT_FILE = {"demo"}


def run(argv: list[str]) -> tuple[object, list[str]]:
    """(exit status or the escaping exception, non-empty stderr lines) of one in-process run."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code: object = courtside(argv)
        except BaseException as exc:  # noqa: BLE001 - anything escaping the dispatcher is the failure shown
            code = exc
    return code, [line for line in err.getvalue().splitlines() if line.strip()]


def test_every_subcommand_has_a_bad_file_case():
    assert set(available_commands()) - NO_INPUT_FILE == set(BAD_FILE)


@pytest.mark.parametrize("command", sorted(available_commands()))
def test_bad_argument_is_one_line_and_exit_2(command):
    code, lines = run([command, "--no-such-option", "1"])
    assert code == 2 and len(lines) == 1, (code, lines)
    assert lines[0].startswith(f"courtside {command}") and "--help" in lines[0], lines  # argparse's own reason


@pytest.mark.parametrize("command", sorted(BAD_FILE))
def test_bad_file_is_one_line_naming_it_and_exit_2(command, tmp_path: Path):
    name, argv = BAD_FILE[command]
    bad = tmp_path / name
    bad.write_bytes(GARBAGE)
    code, lines = run([command, *(a.replace("{bad}", str(bad)).replace("{d}", str(tmp_path)) for a in argv)])
    assert code == 2 and len(lines) == 1, (code, lines)
    assert str(bad) in lines[0] and "Traceback" not in lines[0], lines
