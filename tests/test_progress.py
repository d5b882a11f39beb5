"""Progress bars of the long commands: drawn when stderr is a terminal (a real pseudo-terminal here), absent from a
pipe (a CI log) and with ``--quiet`` -- the whole contract of engine/progress.py, checked through real commands in
their own processes (an engine command and the gateway's export)."""
from __future__ import annotations

import fcntl
import os
import pty
import select
import struct
import termios
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from gateway.recorder import Recorder

ROOT = Path(__file__).resolve().parents[1]


def _run(args: list[str], stderr_tty: bool) -> str:
    """Run ``courtside <args>`` (through the dispatcher module, so the tree under test is used); return stderr.
    With ``stderr_tty`` the child's stderr is the slave side of a new pty and is read from the master side."""
    cmd = [sys.executable, "-m", "gateway.cli", *args]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if not stderr_tty:
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        return done.stderr
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))  # an operator's window
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=slave, stdin=subprocess.DEVNULL)
    os.close(slave)
    chunks = []
    deadline = time.monotonic() + 300
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 0.5)
            if ready:
                try:
                    data = os.read(master, 65536)
                except OSError:  # EIO: every slave descriptor closed (the child exited)
                    break
                if not data:
                    break
                chunks.append(data)
            elif proc.poll() is not None:
                break
    finally:
        os.close(master)
    assert proc.wait(60) == 0, b"".join(chunks).decode(errors="replace")
    return b"".join(chunks).decode(errors="replace")


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    """A real recording written by the gateway's recorder: 2 stations, 800 chunks of samples."""
    rec = Recorder(tmp_path_factory.mktemp("rec"), flush_interval_s=0.01)
    rec.start("take", meta={"stations": ["a", "b"]})
    for i in range(400):
        counter = np.arange(i * 10, i * 10 + 10, dtype=np.uint32)
        batch = {"counter": counter, "t_host_s": counter * 0.01, "acc_g": np.zeros((10, 3), np.float32)}
        rec.put_samples("a", 0, batch)
        rec.put_samples("b", 1, batch)
    return Path(rec.stop()["files"][0])


def _commands(tmp: Path, recording: Path) -> dict[str, tuple[list[str], str]]:
    """Each command with the bar label it must draw on a terminal."""
    return {"build-graph": (["build-graph", "--sample", "--max-clips", "3", "--no-connect", "-o",
                             str(tmp / "g.npz")], "loading clips"),
            "gateway export": (["gateway", "export", str(recording), "--npz", str(tmp / "e.npz")],
                               "reading ")}


@pytest.mark.parametrize("name", ["build-graph", "gateway export"])
def test_progress_on_a_terminal_only(name, tmp_path, recording):
    args, label = _commands(tmp_path, recording)[name]
    on_tty = _run(args, stderr_tty=True)
    assert label in on_tty and "%|" in on_tty, on_tty  # a bar with its label is drawn
    piped = _run(args, stderr_tty=False)
    assert label not in piped and "\r" not in piped and "%|" not in piped, piped
    quiet = _run([*args, "--quiet"], stderr_tty=True)
    assert label not in quiet and "%|" not in quiet, quiet
