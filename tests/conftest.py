"""Shared fixtures: where the real mocap lives, the shipped CMU clips, and offscreen Qt by default."""
from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest

from bench.support.shared_data import find_shared_mocap

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")


@pytest.fixture(scope="session")
def shared_mocap() -> Path:
    path = find_shared_mocap()
    if path is None:
        pytest.skip("the shared real-mocap set is not present (set COURTSIDE_MOCAP_DIR)")
    return path


@pytest.fixture(scope="session")
def native_motions() -> list:
    """The CMU subject-16 clips shipped in engine/data (always present), in name order, at their own 120 Hz."""
    from engine.mocap import load_clip
    from engine.stream.databases import shipped_clip_paths

    return [load_clip(path) for path in shipped_clip_paths().values()]


@pytest.fixture(scope="session")
def motions() -> list:
    """The same clips at the graph rate (30 Hz)."""
    from engine.mocap import load_database
    from engine.stream.databases import GRAPH_FPS, shipped_clip_paths

    return load_database(list(shipped_clip_paths().values()), fps=GRAPH_FPS)


def running_children() -> dict[int, str]:
    """This process's child processes that are still running (pid -> command line). Exited-but-unreaped ones
    (zombies) are left out: they use no CPU. Linux /proc; empty elsewhere."""
    pids: set[int] = set()
    try:
        for tid in os.listdir("/proc/self/task"):
            with open(f"/proc/self/task/{tid}/children") as f:
                pids.update(int(p) for p in f.read().split())
    except OSError:
        return {}
    out = {}
    for pid in pids:
        try:
            with open(f"/proc/{pid}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] == "Z":
                    continue
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                out[pid] = f.read().replace(b"\0", b" ").decode(errors="replace").strip()
        except OSError:
            continue  # exited meanwhile
    return out


@pytest.fixture(autouse=True)
def no_child_process_outlives_its_test():
    """Fail a test that leaves a child process running (and end that process).

    Why: the suite runs serially on a 2-core CI box; a gateway, emulator or console subprocess a test forgot keeps
    taking CPU through every later test, and the timing-sensitive ones (the acceptance clock) then fail far from the
    cause. An audit of tests/gateway and tests/gui found no such leftover; this keeps it that way. A child that was
    told to stop gets 5 s to exit."""
    before = set(running_children())
    yield
    deadline = time.monotonic() + 5.0
    while (left := {p: c for p, c in running_children().items() if p not in before}) and time.monotonic() < deadline:
        time.sleep(0.05)
    if left:
        for pid in left:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        pytest.fail("left running after the test (now killed): " + "; ".join(f"{p} {c}" for p, c in left.items()))
