"""Console frame rate and GUI-thread latency with 4 stations x 6 sensors x 100 Hz, with one and two synthesizers.

    QT_QPA_PLATFORM=offscreen .venv/bin/python bench/bench_console.py [--seconds 20]

A real gateway (`courtside gateway --emulate 4`: four real-time emulated base stations on ptys, 6 sensors each at
100 Hz) runs in its own process, as it would beside the court; this process runs the console window (1500x950,
traces + skeleton view + synthesis worker on station st1) connected over TCP.

Three phases in the same run, so the numbers can be read as ratios on whatever machine runs them:
  baseline  the same Qt event loop with only a bare QTimer at the console's refresh interval and the latency probe;
  1 synth   the full console window on the live gateway (its own synthesis worker);
  2 synth   the same plus a second synthesis worker on the same stream (what a second athlete costs the machine).
Measured: ticks/s of the refresh timer, trace redraws/s and skeleton frames/s (each tick does at most one of
them, gui/main_window.py), GUI-thread cost per tick (mean, p95, max) and its stages, event-loop latency (a probe
thread emits a queued signal every 20 ms; latency = emit -> slot on the GUI thread), and the age of the newest
sample on screen (gateway clock now - newest sample time, at each tick). CPU time of the GUI thread and of the
whole process (per second of the phase, and the GUI thread's per heavy redraw) reads the cost without the queue
for the CPU that a loaded machine adds to every wall-clock rate; the synthesizers run in child processes
(gui/synthesis_process.py), whose CPU is read from /proc.
"""
from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6 import QtCore  # noqa: E402

from gateway.client import GatewayClient  # noqa: E402
from gui.app import application, pump  # noqa: E402
from engine.stream.registry import adapter  # noqa: E402
from gui.engine_link import synthesis_setup  # noqa: E402
from gui.main_window import TICK_MS, ConsoleWindow  # noqa: E402
from gui.synthesis_process import start_synthesis  # noqa: E402


class LatencyProbe(QtCore.QObject):
    """Emits from a worker thread every ``period_s``; the GUI-thread slot records emit->run latency."""

    ping = QtCore.Signal(float)

    def __init__(self, period_s: float = 0.02) -> None:
        super().__init__()
        self.period_s = period_s
        self.latencies_s: list[float] = []
        self.ping.connect(self._pong, QtCore.Qt.QueuedConnection)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _pong(self, t_sent: float) -> None:
        self.latencies_s.append(time.perf_counter() - t_sent)

    def _run(self) -> None:
        while not self._stop.wait(self.period_s):
            self.ping.emit(time.perf_counter())

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def process_cpu_s(pid: int | None) -> float:
    """CPU seconds (user + system) a process has used so far, from /proc (0 when it is gone or unknown)."""
    try:
        fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    except (OSError, TypeError):
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def stats_ms(values_s: list[float]) -> tuple[float, float, float]:
    a = np.asarray(values_s) * 1e3
    return (float(a.mean()), float(np.percentile(a, 95)), float(a.max())) if len(a) else (float("nan"),) * 3


def baseline(seconds: float) -> dict:
    nan = float("nan")
    ticks: list[float] = []
    timer = QtCore.QTimer()
    timer.setTimerType(QtCore.Qt.PreciseTimer)
    timer.timeout.connect(lambda: ticks.append(time.perf_counter()))
    probe = LatencyProbe()
    timer.start(TICK_MS)
    probe.start()
    pump(seconds)
    probe.stop()
    timer.stop()
    return {"fps": (len(ticks) - 1) / (ticks[-1] - ticks[0]), "tick": (0.0, 0.0, 0.0), "gui_cpu_ms_per_s": nan,
            "cpu_ms_per_s": nan, "gui_cpu_ms_per_redraw": nan, "synthesis_cpu_ms_per_s": nan,
            "latency": stats_ms(probe.latencies_s), "age": (float("nan"),) * 3, "stages": {},
            "traces_per_s": float("nan"), "skeleton_per_s": float("nan"), "samples_per_s": float("nan"),
            "synthesis_fps": float("nan")}


def console(seconds: float, port: int, synthesizers: int) -> dict:
    client = GatewayClient("127.0.0.1", port).connect()
    deadline = time.monotonic() + 20
    while len(client.list_stations()) < 4 or any(s["link"] != "streaming" for s in client.list_stations()):
        if time.monotonic() > deadline:
            raise RuntimeError(f"gateway stations not streaming: {client.list_stations()}")
        time.sleep(0.2)
    setup = synthesis_setup(adapter("motion-graph").shipped_spec(), [("st1", i) for i in range(6)])
    window = ConsoleWindow(client, synthesis=setup)
    extra = [start_synthesis(setup) for _ in range(synthesizers - 1)]  # more synthesizers on the same stream
    for worker in extra:
        window.bridge.sample_sinks.append(worker.add_samples)
        window.bridge.camera_sinks.append(worker.add_camera)
    window.resize(1500, 950)
    window.show()
    pump(3.0)  # warm up: groups appear, plots are created
    ages: list[float] = []
    costs: list[float] = []
    tick_times: list[float] = []
    original = window.tick

    def measured_tick() -> None:
        t = time.perf_counter()
        original()
        costs.append(time.perf_counter() - t)
        tick_times.append(t)
        latest = window.store.latest_time()
        if latest is not None:
            ages.append(window.gateway_now_s() - latest)

    window.timer.timeout.disconnect()
    window.timer.timeout.connect(measured_tick)
    window.stats.stage_s.clear()
    window.stats.stage_n.clear()
    probe = LatencyProbe()
    probe.start()
    children = [getattr(w, "pid", None) for w in [window.worker] + extra]  # synthesizers in child processes
    gui_cpu0, cpu0 = time.thread_time(), time.process_time()
    child_cpu0 = sum(process_cpu_s(pid) for pid in children)
    pump(seconds)
    gui_cpu_s, cpu_s = time.thread_time() - gui_cpu0, time.process_time() - cpu0
    child_cpu_s = sum(process_cpu_s(pid) for pid in children) - child_cpu0
    probe.stop()
    n = len(costs)
    span_s = tick_times[-1] - tick_times[0]
    result = {"fps": (n - 1) / span_s, "tick": stats_ms(costs),
              "latency": stats_ms(probe.latencies_s), "age": stats_ms(ages),
              "stages": {k: 1e3 * v / n for k, v in window.stats.stage_s.items()},
              "traces_per_s": window.stats.stage_n.get("traces", 0) / span_s,
              "skeleton_per_s": window.stats.stage_n.get("skeleton", 0) / span_s,
              "samples_per_s": window.bridge.samples_received / (seconds + 3.0),
              "gui_cpu_ms_per_s": 1e3 * gui_cpu_s / seconds, "cpu_ms_per_s": 1e3 * cpu_s / seconds,
              "synthesis_cpu_ms_per_s": 1e3 * child_cpu_s / seconds,
              "gui_cpu_ms_per_redraw": 1e3 * gui_cpu_s / max(1, window.stats.stage_n.get("traces", 0)
                                                              + window.stats.stage_n.get("skeleton", 0)),
              "synthesis_fps": min([window.worker.stats.frames_per_s] + [w.stats.frames_per_s for w in extra])}
    for worker in extra:
        worker.stop()
        worker.join(timeout=2)
    window.shutdown()
    window.close()
    client.close()
    return result


def report(seconds: float, base: dict, runs: dict[str, dict]) -> None:
    """The table: each console run beside the bare-timer baseline, with its ratio to it."""
    print(f"console bench: 4 stations x 6 sensors x 100 Hz, {seconds:g} s per phase, refresh timer {TICK_MS} ms, "
          f"load avg {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"{'':28s}{'baseline':>10s}" + "".join(f"{name:>10s}{'ratio':>7s}" for name in runs))

    def row(label: str, key: str, k: int | None = None, fmt: str = "10.1f", ratio: bool = True) -> None:
        def get(r: dict) -> float:
            return r[key] if k is None else r[key][k]
        b = get(base)
        cells = "".join(f"{get(r):{fmt}}" + (f"{get(r) / b:7.2f}" if ratio and b == b and b else f"{'-':>7s}")
                        for r in runs.values())
        print(f"{label:28s}{b:{fmt}}{cells}")

    row("refresh ticks/s", "fps")
    row("trace redraws/s", "traces_per_s", ratio=False)
    row("skeleton frames/s", "skeleton_per_s", ratio=False)
    for k, label in enumerate(("mean", "p95", "max")):
        row(f"event-loop latency {label} ms", "latency", k, "10.2f")
    for k, label in enumerate(("mean", "p95", "max")):
        row(f"GUI tick cost {label} ms", "tick", k, "10.2f", ratio=False)
    for name in sorted({s for r in runs.values() for s in r["stages"]}):
        print(f"{'  stage ' + name + ' ms/tick':28s}{'-':>10s}"
              + "".join(f"{r['stages'].get(name, 0.0):10.2f}{'-':>7s}" for r in runs.values()))
    for k, label in enumerate(("mean", "p95", "max")):
        row(f"newest sample age {label} ms", "age", k, ratio=False)
    row("GUI thread CPU ms per s", "gui_cpu_ms_per_s", ratio=False)
    row("GUI CPU ms per redraw", "gui_cpu_ms_per_redraw", ratio=False)
    row("console process CPU ms per s", "cpu_ms_per_s", ratio=False)
    row("synthesis processes CPU ms/s", "synthesis_cpu_ms_per_s", ratio=False)
    row("samples/s received", "samples_per_s", fmt="10.0f", ratio=False)
    row("synthesis frames/s (min)", "synthesis_fps", ratio=False)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    args = parser.parse_args()
    application()
    port = free_port()
    with tempfile.TemporaryDirectory() as rec:
        gateway = subprocess.Popen([sys.executable, "-m", "gateway.cli", "gateway", "--emulate", "4", "--quiet",
                                    "--listen", f"127.0.0.1:{port}", "--record-dir", rec],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            for _ in range(100):
                try:
                    socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
                    break
                except OSError:
                    time.sleep(0.1)
            base = baseline(args.seconds / 2)
            runs = {f"{k} synth": console(args.seconds, port, k) for k in (1, 2)}
        finally:
            gateway.terminate()
            gateway.wait(10)
    report(args.seconds, base, runs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
