"""`courtside gateway` stops on SIGTERM whichever of its threads the kernel hands the signal to.

A signal aimed at the process may be taken by any thread that does not block it (under strace, or with native
library threads around: liblsl, the x-IMU3 driver). Python runs the handler only when the main thread runs
bytecode; a main thread parked in an untimed wait would never see it (found as the LSL cross-process test hanging
under strace -f until its 240 s timeout)."""
from __future__ import annotations

import ctypes
import os
import platform
import signal
import subprocess
import sys

import pytest

TGKILL = {"x86_64": 234, "aarch64": 131}.get(platform.machine())


def _takes_sigterm(pid: int, tid: int) -> bool:
    with open(f"/proc/{pid}/task/{tid}/status") as fh:
        blocked = int(next(line for line in fh if line.startswith("SigBlk:")).split()[1], 16)
    return not blocked & (1 << (signal.SIGTERM - 1))


@pytest.mark.skipif(TGKILL is None or not os.path.isdir("/proc/self/task"), reason="Linux tgkill needed")
def test_sigterm_taken_by_a_worker_thread_stops_the_gateway(tmp_path):
    proc = subprocess.Popen([sys.executable, "-m", "gateway.cli", "gateway", "--emulate", "1", "--listen",
                             "127.0.0.1:0", "--record-dir", str(tmp_path), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        while "gateway listening" not in (line := proc.stdout.readline()):
            assert line, proc.stderr.read()
        workers = [int(t) for t in os.listdir(f"/proc/{proc.pid}/task")
                   if int(t) != proc.pid and _takes_sigterm(proc.pid, int(t))]
        assert workers
        assert ctypes.CDLL(None, use_errno=True).syscall(TGKILL, proc.pid, workers[0], signal.SIGTERM) == 0
        out, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0 and "gateway stopped" in out, err[-2000:]
