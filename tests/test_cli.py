"""The `courtside` dispatcher: every declared subcommand resolves, and the headless side never pulls in Qt."""
from __future__ import annotations

import subprocess
import sys

from gateway.cli import available_commands, main


def test_help_lists_every_declared_subcommand(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in ("emulate", "gateway", "console", "demo", "build-graph", "synthesize", "evaluate"):
        assert name in out


def test_unknown_command_is_a_clear_error(capsys):
    assert main(["no-such-command"]) == 2
    assert "unknown command 'no-such-command'" in capsys.readouterr().err


def test_headless_packages_never_import_gui_or_qt():
    """gateway/, engine/, firmware_protocol/ must import without PySide6/moderngl/gui being loaded."""
    code = (
        "import sys, pkgutil, importlib\n"
        "import gateway, engine, firmware_protocol\n"
        "for pkg in (gateway, engine, firmware_protocol):\n"
        "    for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + '.'):\n"
        "        importlib.import_module(m.name)\n"
        "bad = sorted(n for n in sys.modules if n.split('.')[0] in {'gui', 'PySide6', 'pyqtgraph', 'moderngl'})\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == ""


def test_entry_points_are_declared():
    assert {"emulate", "gateway", "console", "demo"} <= set(available_commands())
