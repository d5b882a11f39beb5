"""Issue 13 "Shape": the daemon's core (data path, server, config, assembly) loads no emulator code; emulation
harnesses live in firmware_protocol.emulator (issue 19: every emulator and fault tool in one place) and are
imported only when a config asks for emulated stations."""
from __future__ import annotations

import subprocess
import sys


def test_daemon_core_imports_no_emulation_harness():
    code = (
        "import sys\n"
        "import gateway.daemon, gateway.assembly, gateway.court_config, gateway.server, gateway.client\n"
        "import gateway.station, gateway.links, gateway.recorder, gateway.auth, gateway.tls, gateway.wire\n"
        "from gateway.daemon.cli import _parser\n"
        "_parser().parse_args(['--port', '/dev/null'])\n"
        "print(sorted(m for m in sys.modules if m.startswith('firmware_protocol.emulator')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True).stdout
    assert out.strip() == "[]", out
