"""Console frame rate and GUI-thread latency with 4 stations x 6 sensors x 100 Hz.

    QT_QPA_PLATFORM=offscreen .venv/bin/python bench/bench_console.py [--seconds 20]

A real gateway (`courtside gateway --emulate 4`: four real-time emulated base stations on ptys, 6 sensors each at
100 Hz) runs in its own process, as it would beside the court; this process runs the console window (1500x950,
traces + skeleton view + synthesis worker on station st1) connected over TCP.

Two phases in the same run, so the numbers can be read as ratios on whatever machine runs them:
  baseline  the same Qt event loop with only a bare 30 Hz QTimer (no console) and the latency probe;
  console   the full console window on the live gateway.
Measured: ticks/s of the 30 Hz refresh timer, GUI-thread cost per tick (mean, p95, max) and its stages, event-loop
latency (a probe thread emits a queued signal every 20 ms; latency = emit -> slot on the GUI thread), and the age
of the newest sample on screen (gateway clock now - newest sample time, at each tick).
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
from gui.main_window import ConsoleWindow  # noqa: E402


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


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def stats_ms(values_s: list[float]) -> tuple[float, float, float]:
    a = np.asarray(values_s) * 1e3
    return (float(a.mean()), float(np.percentile(a, 95)), float(a.max())) if len(a) else (float("nan"),) * 3


def baseline(seconds: float) -> dict:
    ticks: list[float] = []
    timer = QtCore.QTimer()
    timer.setTimerType(QtCore.Qt.PreciseTimer)
    timer.timeout.connect(lambda: ticks.append(time.perf_counter()))
    probe = LatencyProbe()
    timer.start(33)
    probe.start()
    pump(seconds)
    probe.stop()
    timer.stop()
    return {"fps": (len(ticks) - 1) / (ticks[-1] - ticks[0]), "tick": (0.0, 0.0, 0.0),
            "latency": stats_ms(probe.latencies_s), "age": (float("nan"),) * 3, "stages": {}}


def console(seconds: float, port: int) -> dict:
    client = GatewayClient("127.0.0.1", port).connect()
    deadline = time.monotonic() + 20
    while len(client.list_stations()) < 4 or any(s["link"] != "streaming" for s in client.list_stations()):
        if time.monotonic() > deadline:
            raise RuntimeError(f"gateway stations not streaming: {client.list_stations()}")
        time.sleep(0.2)
    window = ConsoleWindow(client, synthesis=synthesis_setup(adapter("motion-graph").shipped_spec(), [("st1", i) for i in range(6)]))
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
    probe = LatencyProbe()
    probe.start()
    pump(seconds)
    probe.stop()
    n = len(costs)
    result = {"fps": (n - 1) / (tick_times[-1] - tick_times[0]), "tick": stats_ms(costs),
              "latency": stats_ms(probe.latencies_s), "age": stats_ms(ages),
              "stages": {k: 1e3 * v / n for k, v in window.stats.stage_s.items()},
              "samples_per_s": window.bridge.samples_received / (seconds + 3.0),
              "synthesis_fps": window.worker.stats.frames_per_s if window.worker else 0.0}
    window.shutdown()
    window.close()
    client.close()
    return result


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
            full = console(args.seconds, port)
        finally:
            gateway.terminate()
            gateway.wait(10)
    print(f"console bench: 4 stations x 6 sensors x 100 Hz, {args.seconds:g} s, load avg {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cores")
    print(f"{'':28s}{'baseline':>12s}{'console':>12s}{'ratio':>8s}")
    print(f"{'refresh ticks/s':28s}{base['fps']:12.1f}{full['fps']:12.1f}{full['fps'] / base['fps']:8.2f}")
    for k, label in enumerate(("mean", "p95", "max")):
        b, f = base["latency"][k], full["latency"][k]
        print(f"{'event-loop latency ' + label + ' ms':28s}{b:12.2f}{f:12.2f}{f / b:8.1f}")
    for k, label in enumerate(("mean", "p95", "max")):
        print(f"{'GUI tick cost ' + label + ' ms':28s}{'-':>12s}{full['tick'][k]:12.2f}")
    for name, ms in full["stages"].items():
        print(f"{'  stage ' + name + ' ms':28s}{'-':>12s}{ms:12.2f}")
    for k, label in enumerate(("mean", "p95", "max")):
        print(f"{'newest sample age ' + label + ' ms':28s}{'-':>12s}{full['age'][k]:12.1f}")
    print(f"{'samples/s received':28s}{'-':>12s}{full['samples_per_s']:12.0f}")
    print(f"{'synthesis frames/s':28s}{'-':>12s}{full['synthesis_fps']:12.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
