"""The console's synthesizer in a child process: the controls reach the child's worker, and the child never
outlives the console (the live = offline bit-for-bit checks run on both runners in test_synthesis.py)."""
from __future__ import annotations

import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np

from engine.stream.registry import adapter
from gui.engine_link import synthesis_setup
from gui.synthesis_process import SynthesisProcess

REPO = Path(__file__).resolve().parents[2]


def wait_for(condition, timeout_s: float = 20.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def test_lag_and_reset_reach_the_child_and_come_back_in_its_stats_and_poses():
    spec = adapter("motion-graph").shipped_spec()
    sensors = [("st0", k) for k in range(len(spec.sensor_names))]
    synth = SynthesisProcess(synthesis_setup(spec, sensors, lag_s=0.3), keep_poses=True)
    synth.start()
    try:
        t0 = 50.0
        t = t0 + np.arange(300) / 100.0   # 3 s of a sensor at rest (1 g up) on every sensor
        for key in sensors:
            synth.add_samples(key, t, np.tile([0.0, 1.0, 0.0], (len(t), 1)))
        assert wait_for(lambda: len(synth.poses()[1]) > 30), synth.stats
        assert synth.latest_pose() is not None and synth.stats.lag_s == 0.3
        synth.set_lag(1.0)
        assert wait_for(lambda: synth.stats.lag_s == 1.0), synth.stats
        synth.reset()   # a playback seek: the kept poses start over, nothing shown until new frames decide
        assert synth.latest_pose() is None
        assert wait_for(lambda: synth.poses()[1] == []), len(synth.poses()[1])
        assert synth.stats.error == ""
    finally:
        synth.stop()
        synth.join(timeout=5)
    assert not synth.is_alive()


CONSOLE = textwrap.dedent("""
    import sys, time
    from engine.stream.registry import adapter
    from gui.engine_link import synthesis_setup
    from gui.synthesis_process import SynthesisProcess
    spec = adapter("motion-graph").shipped_spec()
    synth = SynthesisProcess(synthesis_setup(spec, [("st0", k) for k in range(len(spec.sensor_names))]))
    synth.start()
    print(synth.pid, flush=True)
    time.sleep(600)
""")


def test_the_child_ends_when_the_console_is_killed():
    """A console killed outright (SIGKILL: no shutdown) must not leave its synthesizer running: the child sees
    its command pipe end and exits."""
    console = subprocess.Popen([sys.executable, "-c", CONSOLE], cwd=REPO, stdout=subprocess.PIPE, text=True)
    try:
        child = int(console.stdout.readline())
        assert Path(f"/proc/{child}").exists()
        console.kill()
        console.wait(10)
        assert wait_for(lambda: not _running(child), 10.0), f"synthesis child {child} outlived its console"
    finally:
        console.kill()


def _running(pid: int) -> bool:
    """The pid exists and is not a zombie (a reaped-late child of init counts as gone)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state != "Z"


def test_the_child_holds_no_socket_of_the_console():
    """A gateway running in the console's process (tests, the demo) must be able to restart on its port while a
    synthesizer runs: the fork's copy of the listening socket is closed in the child."""
    import socket

    server = socket.socket()
    server.bind(("127.0.0.9", 0))
    server.listen()
    address = server.getsockname()
    spec = adapter("motion-graph").shipped_spec()
    synth = SynthesisProcess(synthesis_setup(spec, [("st0", k) for k in range(len(spec.sensor_names))]))
    synth.start()
    try:
        assert wait_for(lambda: synth.stats.lag_s == 0.5 and _sockets_of(synth.pid) == 0, 10.0), _sockets_of(synth.pid)
        server.close()
        again = socket.socket()
        again.bind(address)   # "address already in use" if the child still held the listener
        again.close()
    finally:
        synth.stop()
        synth.join(timeout=5)


def _sockets_of(pid: int) -> int:
    """Open sockets of a process (an fd closed while we look is skipped)."""
    count = 0
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            count += "socket:" in str(fd.readlink())
        except FileNotFoundError:
            pass
    return count


def test_an_engine_that_streams_its_poses_out_stays_in_the_console_process():
    """`--stream-bvh` / `--stream-vmc` engines own a server thread and sockets of the console's process, which a
    forked child would not have (the child closes what it inherits): they run as a thread; plain engines fork."""
    import socket

    from engine.livestream.console import streaming_engine
    from gui.synthesis import SynthesisWorker
    from gui.synthesis_process import start_synthesis

    spec = adapter("motion-graph").shipped_spec()
    sensors = [("st0", k) for k in range(len(spec.sensor_names))]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as receiver:
        receiver.bind(("127.0.0.1", 0))
        streaming = streaming_engine(spec, vmc=f"127.0.0.1:{receiver.getsockname()[1]}")
        runners = [start_synthesis(synthesis_setup(s, sensors)) for s in (streaming, spec)]
        try:
            assert isinstance(runners[0], SynthesisWorker) and isinstance(runners[1], SynthesisProcess)
            assert runners[1].is_alive()
        finally:
            for runner in runners:
                runner.stop()
                runner.join(timeout=5)


def test_restart_budget_allows_a_bounded_number_within_its_window():
    from gui.restart_budget import RestartBudget

    budget = RestartBudget(max_restarts=3, window_s=60.0)
    assert [budget.take(t) for t in (0.0, 10.0, 20.0, 30.0)] == [True, True, True, False]
    assert budget.used == 3
    assert budget.take(60.5) and budget.used == 3  # the first restart left the window: one more is allowed


def test_a_killed_child_is_reaped_and_restarted_until_the_budget_is_spent(caplog):
    """SIGKILL of the child: it is reaped (no zombie), a new child runs with the lag asked for last and decides
    poses again, the fault says so and is logged; after the budget a dead child stays dead and says that."""
    import logging
    import os
    import signal

    spec = adapter("motion-graph").shipped_spec()
    sensors = [("st0", k) for k in range(len(spec.sensor_names))]
    synth = SynthesisProcess(synthesis_setup(spec, sensors, lag_s=0.3))
    synth.start()
    try:
        synth.set_lag(0.4)
        assert wait_for(lambda: synth.stats.lag_s == 0.4), synth.stats
        with caplog.at_level(logging.WARNING, logger="courtside.console"):
            for n in (1, 2, 3):
                dead = synth.pid
                os.kill(dead, signal.SIGKILL)
                assert wait_for(lambda: synth.pid != dead and synth.is_alive(), 10.0)
                assert not _running(dead) and not Path(f"/proc/{dead}").exists()  # reaped, not a zombie
                assert synth.fault == f"synthesis restarted after crash ({n}/3): killed by signal 9"
            t = 50.0 + np.arange(200) / 100.0
            for key in sensors:
                synth.add_samples(key, t, np.tile([0.0, 1.0, 0.0], (len(t), 1)))
            assert wait_for(lambda: synth.latest_pose() is not None), synth.stats
            assert synth.stats.lag_s == 0.4  # the restarted child kept the operator's lag
            assert [n for n, _ in synth.recent_poses(0)] == sorted({n for n, _ in synth.recent_poses(0)})
            dead = synth.pid
            os.kill(dead, signal.SIGKILL)
            assert wait_for(lambda: synth.fault.startswith("synthesis stopped"), 10.0), synth.fault
            assert not synth.is_alive() and not Path(f"/proc/{dead}").exists()
            assert synth.latest_pose() is None and synth.stats.frames_per_s == 0.0
        assert caplog.text.count("restarting") == 3 and "crashed 4 times within 60 s" in caplog.text
    finally:
        synth.stop()
        synth.join(timeout=5)


def test_starting_a_synthesizer_holds_blas_to_one_thread_so_a_later_fork_cannot_deadlock():
    """OpenBLAS's fork handler and another thread's multi-threaded BLAS call deadlock each other (module doc of
    gui/synthesis_process.py; seen in CI with a streaming engine's thread and a second athlete's fork): after
    `start_synthesis` every BLAS library runs one thread, whatever it ran before."""
    from threadpoolctl import threadpool_info, threadpool_limits

    from gui.synthesis_process import start_synthesis

    spec = adapter("motion-graph").shipped_spec()
    with threadpool_limits(limits=2, user_api="blas"):  # restores the original limits on leaving
        assert max(lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas") == 2
        runner = start_synthesis(synthesis_setup(spec, [("st0", k) for k in range(len(spec.sensor_names))]))
        try:
            assert {lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"} == {1}
        finally:
            runner.stop()
            runner.join(timeout=5)
