"""Live synthesis in a child process: `SynthesisWorker`'s interface, its thread running in a forked child.

Why a process: Python runs one thread at a time per interpreter. With the engine in a thread of the console's
process, every engine step holds the GUI thread off the interpreter lock, so on a 2-core laptop the console
process never got past one core, the traces and the 3-D view waited on the engine (measured with
`bench/bench_console.py`: GUI tick p95 60 ms with two synthesizers) and the redraw rate fell with each athlete.
In a child the engine has its own interpreter and core; the console process keeps the GUI, the network reader
and a small receiver thread.

Why fork (not spawn): the child starts with the engine already loaded (a database, its kd-trees, the posing
tables: seconds to rebuild, and closures that do not pickle), shared copy-on-write. It touches no Qt object, runs
only `SynthesisWorker` and this module's loop, and ends with the console (end of its command pipe). The same
worker code runs in both cases, so live and offline still agree bit for bit. Where fork does not exist
(Windows, macOS's default), `start_synthesis` falls back to the thread.

Wire: the console sends ``(method, args)`` of the worker's inputs (`add_samples`, `add_camera`,
`recording_started`, `set_lag`, `reset`) down one pipe, and the child sends back, when anything changed,
``(stats, whether the newest pose changed, that pose, the recent poses not sent yet, kept-poses epoch, first
frame, new kept poses)`` up another.

A child that dies (SIGKILL, the OOM killer) is reaped at once and restarted from the same setup, a bounded number
of times (`gui.restart_budget`); each restart and the giving up are logged and kept in `SynthesisProcess.fault`
for the console's athlete status, and the dead child's figures (frames/s, confidence) are dropped, not shown
as if it still ran.

Why one BLAS thread (`_one_blas_thread`): OpenBLAS's fork handler shuts its worker threads down, and a fork while
another thread of the console is inside a multi-threaded BLAS call deadlocks both (seen in CI: the main thread in
`blas_thread_shutdown_` forking a second athlete's child, an in-process streaming engine's matrix product waiting
on its workers; the console hung for good). With one BLAS thread no worker threads exist; the children inherit
it, which the live engines want anyway (engine/olng/threads.py: tiny matrices, threads only wait on each
other)."""
from __future__ import annotations

import collections
import logging
import multiprocessing
import os
import signal
import stat
import threading
import time
from collections.abc import Hashable
from dataclasses import replace
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from engine.stream import FramePose

from gui.restart_budget import RestartBudget
from gui.synthesis import RECENT_POSES, SynthesisSetup, SynthesisStats, SynthesisWorker

log = logging.getLogger("courtside.console")
# One fork at a time in this process: a child forked between another's `Process.start` and the closing of that
# child's pipe ends in the console would hold those ends open, and the other child's death would go unseen.
_FORK_LOCK = threading.Lock()
PUBLISH_S = 0.01  # the child looks for a new pose this often (s): the display's added latency at most
MAX_INPUTS_PER_PUBLISH = 256  # inputs handled between two looks, so a flood of samples never starves the poses


def _serve(setup: SynthesisSetup, keep_poses: bool, inputs: Connection, updates: Connection,
           console_ends: tuple[Connection, ...]) -> None:
    """The child: a `SynthesisWorker` fed from `inputs`, its outputs published on `updates` until `inputs` ends
    (a None, or the console gone)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl+C in the console's terminal is the console's to handle
    for end in console_ends:  # the fork copied the console's ends: held here they would hide its exit
        end.close()
    _close_inherited_sockets()
    worker = SynthesisWorker(setup, keep_poses=keep_poses)
    worker.start()
    publisher = _Publisher(worker, updates)
    try:
        while _take_inputs(worker, inputs):
            publisher.publish()
    except (EOFError, OSError):  # the console is gone
        return
    finally:
        worker.stop()
        worker.join(timeout=2)
    publisher.publish()  # what the worker decided up to its stop (a stopped console's --save-poses)


def _close_inherited_sockets() -> None:
    """Close every socket the fork copied (the gateway connection, a listening server in the same process, the
    BVH / VMC streams): held open here they would keep a connection the console closed alive, or a port busy for
    a gateway restarting on it. The child talks to the console over pipes only."""
    for name in os.listdir("/proc/self/fd") if os.path.isdir("/proc/self/fd") else ():
        fd = int(name)
        try:
            if stat.S_ISSOCK(os.fstat(fd).st_mode):
                os.close(fd)
        except OSError:  # the directory's own fd, gone already
            pass


def _take_inputs(worker: SynthesisWorker, inputs: Connection) -> bool:
    """Hand what arrived (waiting up to PUBLISH_S for the first) to the worker; False once told to stop."""
    for k in range(MAX_INPUTS_PER_PUBLISH):
        if not inputs.poll(PUBLISH_S if k == 0 else 0):
            break
        message = inputs.recv()
        if message is None:
            return False
        method, args = message
        getattr(worker, method)(*args)
    return True


class _Publisher:
    """Sends the worker's outputs up the pipe when they changed: stats, newest pose, and the kept poses the
    console has not seen yet (`SynthesisWorker.kept_poses_since`)."""

    def __init__(self, worker: SynthesisWorker, updates: Connection) -> None:
        self.worker, self.updates = worker, updates
        self.stats: SynthesisStats | None = None
        self.pose: FramePose | None = None
        self.epoch, self.n_sent = -1, 0
        self.last_recent = 0  # number of the last recent pose sent

    def publish(self) -> None:
        worker = self.worker
        if worker.keep_poses:
            epoch, start, new = worker.kept_poses_since(self.epoch, self.n_sent)
        else:
            epoch, start, new = self.epoch, worker.stats.start_frame, []
        self.n_sent = len(new) + (self.n_sent if epoch == self.epoch else 0)
        pose = worker.latest_pose()
        pose_changed = pose is not self.pose
        recent = worker.recent_poses(self.last_recent)
        if new or recent or epoch != self.epoch or pose_changed or worker.stats != self.stats:
            self.stats, self.pose = replace(worker.stats), pose  # a copy: the worker goes on updating its own
            # an unchanged pose is not sent again: the console keeps its object, so it knows nothing new came
            self.updates.send((self.stats, pose_changed, pose if pose_changed else None, recent, epoch, start, new))
            self.last_recent = recent[-1][0] if recent else self.last_recent
        self.epoch = epoch


class SynthesisProcess:
    """`SynthesisWorker`'s interface (inputs from any thread, newest pose / kept poses / stats out) with the
    worker in a forked child process (module doc)."""

    def __init__(self, setup: SynthesisSetup, keep_poses: bool = False) -> None:
        self.setup = setup
        self.keep_poses = keep_poses
        self.stats = SynthesisStats(lag_s=setup.lag_s)
        self.fault = ""  # the child's crashes, restarts or giving up, for the operator; "" while none happened
        self._worn = frozenset(setup.sensors)
        self._lag_s = setup.lag_s  # the newest lag asked for: a restarted child starts with it
        self._lock = threading.Lock()      # the outputs, written by the receiver thread
        self._send_lock = threading.Lock()  # the input pipe: the network reader and the GUI thread both send
        self._pose: FramePose | None = None
        self._poses: list[FramePose] = []
        self._recent: collections.deque[tuple[int, FramePose]] = collections.deque(maxlen=RECENT_POSES)
        self._recent_base = 0  # added to a child's recent-pose numbers: they go on rising across restarts
        self._epoch = -1
        self._start_frame: int | None = None
        self._process: multiprocessing.process.BaseProcess | None = None
        self._receiver: threading.Thread | None = None
        self._inputs: Connection | None = None
        self._updates: Connection | None = None
        self._stopping = False
        self._budget = RestartBudget()

    def start(self) -> None:
        self._spawn()
        self._receiver = threading.Thread(target=self._receive, name="console-synthesis-receiver", daemon=True)
        self._receiver.start()

    def _spawn(self) -> None:
        """Fork a child running the setup at the newest lag; its pipes and process replace the previous ones."""
        context = multiprocessing.get_context("fork")
        with _FORK_LOCK:
            child_inputs, inputs = context.Pipe(duplex=False)
            updates, child_updates = context.Pipe(duplex=False)
            process = context.Process(target=_serve, name="courtside-synthesis", daemon=True,
                                      args=(replace(self.setup, lag_s=self._lag_s), self.keep_poses, child_inputs,
                                            child_updates, (inputs, updates)))
            process.start()
            child_inputs.close()   # the child's ends: only the child holds them now, so its exit is seen here
            child_updates.close()
        if self._inputs is not None:
            self._inputs.close()  # the dead child's input end
        self._inputs, self._updates, self._process = inputs, updates, process

    # -- inputs (any thread) -----------------------------------------------------------------------------------
    def add_samples(self, sensor: Hashable, t_s: np.ndarray, acc_g: np.ndarray, quat_wxyz: np.ndarray | None = None,
                    gyro_rps: np.ndarray | None = None) -> None:
        """Only the sensors the engine reads cross the pipe (the bridge offers every sensor of the court)."""
        if sensor in self._worn:
            self._send("add_samples", sensor, t_s, acc_g, quat_wxyz, gyro_rps)

    def add_camera(self, t_s: float, position_m: Any, heading_rad: float | None) -> None:
        self._send("add_camera", t_s, position_m, heading_rad)

    def recording_started(self, started_t_host_s: float) -> None:
        self._send("recording_started", started_t_host_s)

    def set_lag(self, lag_s: float) -> None:
        self._lag_s = lag_s
        self._send("set_lag", lag_s)

    def reset(self) -> None:
        with self._lock:
            self._pose = None
        self._send("reset")

    def _send(self, method: str, *args: Any) -> None:
        with self._send_lock:
            if self._inputs is None:
                return
            try:
                self._inputs.send((method, args))
            except (BrokenPipeError, OSError):  # the child died: the receiver sees its pipe end and restarts it
                pass

    def stop(self) -> None:
        with self._send_lock:
            self._stopping = True  # the child's end from now on is the one asked for: no restart
            if self._inputs is not None:
                try:
                    self._inputs.send(None)
                except (BrokenPipeError, OSError):
                    pass

    def join(self, timeout: float | None = None) -> None:
        if self._process is not None:
            self._process.join(timeout)
            if self._process.is_alive():
                self._process.kill()
                self._process.join(1.0)
        if self._receiver is not None:
            self._receiver.join(timeout)
        with self._send_lock:
            if self._inputs is not None:
                self._inputs.close()
                self._inputs = None

    @property
    def pid(self) -> int | None:
        """The child's process id (None before `start`): for CPU accounting and tests."""
        return None if self._process is None else self._process.pid

    def is_alive(self) -> bool:
        return self._process is not None and self._process.is_alive()

    # -- outputs (any thread) ----------------------------------------------------------------------------------
    def latest_pose(self) -> FramePose | None:
        with self._lock:
            return self._pose

    def poses(self) -> tuple[int | None, list[FramePose]]:
        """(first frame of the current session, every pose since) — with ``keep_poses`` only."""
        with self._lock:
            return self._start_frame, list(self._poses)

    def recent_poses(self, after: int) -> list[tuple[int, FramePose]]:
        """(number, pose) of the recent poses numbered after `after` (`SynthesisWorker.recent_poses`)."""
        with self._lock:
            return [(n, pose) for n, pose in self._recent if n > after]

    def _receive(self) -> None:
        """Receiver thread: the child's updates into the output slots; a child that ends unasked is reaped and
        restarted (`_child_ended`)."""
        while True:
            try:
                message = self._updates.recv()
            except (EOFError, OSError):
                self._updates.close()
                if self._child_ended():
                    continue
                return
            self._take(message)

    def _take(self, message: tuple) -> None:
        stats, pose_changed, pose, recent, epoch, start, new = message
        with self._lock:
            self.stats, self._start_frame = stats, start
            if pose_changed:
                self._pose = pose
            self._recent.extend((n + self._recent_base, p) for n, p in recent)
            if epoch != self._epoch:
                self._poses, self._epoch = list(new), epoch
            else:
                self._poses.extend(new)

    def _child_ended(self) -> bool:
        """The child's update pipe ended: reap the child (no zombie), then, unless the console stopped it, drop
        its figures and restart it while the budget allows. True when a new child runs."""
        process = self._process
        process.join(5.0)
        if self._stopping:
            return False
        code = process.exitcode
        cause = f"killed by signal {-code}" if code is not None and code < 0 else f"ended with exit code {code}"
        with self._lock:
            self._pose = None  # neither the dead child's pose nor its frames/s and confidence stay on show
            self.stats = SynthesisStats(lag_s=self._lag_s)
            self._recent_base = self._recent[-1][0] if self._recent else self._recent_base
            self._epoch = -1  # the new child's kept poses start over, as after an engine restart
        label = self.setup.engine.name
        # each fault is logged before it is shown: whoever sees `fault` (the status bar's thread) finds it logged
        if not self._budget.take(time.monotonic()):
            fault = (f"synthesis stopped: its process crashed {self._budget.max_restarts + 1} times within "
                     f"{self._budget.window_s:.0f} s (last {cause}); restart the console")
            log.error("synthesis (%s): process %d %s; %s", label, process.pid, cause, fault)
            self.fault = fault
            return False
        log.warning("synthesis (%s): process %d %s; restarting (%d/%d)", label, process.pid, cause,
                    self._budget.used, self._budget.max_restarts)
        self.fault = f"synthesis restarted after crash ({self._budget.used}/{self._budget.max_restarts}): {cause}"
        with self._send_lock:
            if self._stopping:
                return False
            self._spawn()
        return True


Synthesizer = SynthesisWorker | SynthesisProcess  # the same interface: inputs, latest_pose / poses / stats


def _one_blas_thread() -> None:
    """Hold every BLAS library loaded so far to one thread, for the rest of the process (module doc): before any
    synthesizer starts, so no thread is inside a multi-threaded call when a later one forks."""
    threadpool_limits(limits=1, user_api="blas")


def start_synthesis(setup: SynthesisSetup, keep_poses: bool = False) -> Synthesizer:
    """The console's synthesizer, started: in a child process where fork exists (module doc), else a thread; also
    a thread for an engine that streams its poses out (`EngineSpec.in_process`: its server thread and sockets
    belong to this process, and the child closes the sockets it inherits)."""
    _one_blas_thread()
    forks = "fork" in multiprocessing.get_all_start_methods()
    runner: Synthesizer = SynthesisProcess(setup, keep_poses) if forks and not setup.engine.in_process \
        else SynthesisWorker(setup, keep_poses)
    runner.start()
    return runner
