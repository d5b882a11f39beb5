"""`demo_session`: the demo hardware plus a console window on it — what `courtside demo`, the screenshot script
and tests open."""
from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from gui.demo.hardware import demo_hardware, hardware_in_subprocess
from gui.demo.performance import (OPPONENT, OPPONENT_STATION, PLAYER, Performance, TruthClock, build_opponent,
                                  build_performance, sensor_segments, synthesis_sensors, truth_from_events)

log = logging.getLogger("courtside.demo")


@dataclass
class DemoSession:
    """Everything `courtside demo` runs, for the CLI, the screenshot script and tests."""

    perf: Performance
    address: tuple[str, int]
    client: object   # gateway.client.GatewayClient
    window: object   # gui.main_window.ConsoleWindow


@contextlib.contextmanager
def demo_session(lag_s: float = 0.5, listen: tuple[str, int] = ("127.0.0.1", 0),
                 record_dir: Path = Path("recordings"), camera: bool = True, duration_s: float | None = None,
                 separate_process: bool = True) -> Iterator[DemoSession]:
    """Start the demo hardware (by default in a child process) and open the console window on it."""
    from gateway.client import GatewayClient

    from engine.stream.registry import adapter
    from gui.engine_link import sensor_joints, synthesis_setup
    from gui.main_window import ConsoleWindow

    hardware = hardware_in_subprocess if separate_process else demo_hardware
    perf = build_performance()  # deterministic: the same frames the stations replay, for ground truth here
    held_out = perf.clip_names + build_opponent().clip_names  # both athletes' clips stay out of the graph
    spec = adapter("motion-graph").shipped_spec(exclude=held_out)
    log.info("%s, minus held-out %s", spec.label, ", ".join(held_out))
    with contextlib.ExitStack() as stack:
        address, t0 = stack.enter_context(hardware(listen, record_dir, camera, duration_s))
        client = GatewayClient(*address).connect()
        stack.callback(client.close)
        log.info("demo gateway on %s:%d (connect more consoles with `courtside console --connect ...`)", *address)
        window = ConsoleWindow(client, synthesis=synthesis_setup(spec, synthesis_sensors(), lag_s),
                               truth=TruthClock(perf, t0), truth_for_take=truth_from_events,
                               sensor_segments=sensor_segments(),
                               sensor_joints=sensor_joints(perf.skeleton, sensor_segments()),
                               title="Courtside demo — two athletes, emulated stations replaying held-out CMU mocap",
                               athlete=PLAYER, more_athletes={
                                   OPPONENT: synthesis_setup(spec, synthesis_sensors(OPPONENT_STATION), lag_s)})
        stack.callback(window.shutdown)
        window.resize(1500, 950)
        yield DemoSession(perf, address, client, window)
