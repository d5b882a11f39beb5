"""Emulated base stations served over real ptys, for `courtside gateway --emulate N`, the demo and tests.

Each station is the protocol engineer's `BaseStation` in real-time mode behind a `PtyTransport`, reached through a
stable symlink (``<dir>/station<i>``) so an unplug/replug (new /dev/pts/N) looks like udev's stable by-id path.
`EmulatedStation.true_to_host` converts the emulator's true time into the gateway's monotonic clock, which is what
tests score the clock alignment against.
"""
from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from firmware_protocol.emulator import BaseStation, MotionSource, StationConfig
from firmware_protocol.emulator.link import EmulatorLink
from firmware_protocol.emulator.pty_transport import PtyTransport


@dataclass
class EmulatedStation:
    station: BaseStation
    link: EmulatorLink
    transport: PtyTransport
    path: str  # stable symlink the gateway opens
    wall0_s: float  # host monotonic time at emulator true time 0
    speed: float = 1.0
    _tmpdir: Any = field(default=None, repr=False)

    def true_to_host(self, t_true_s: np.ndarray | float) -> np.ndarray:
        """Emulator true time (s) -> gateway host monotonic time (s)."""
        return self.wall0_s + np.asarray(t_true_s, dtype=np.float64) / self.speed

    def unplug(self) -> None:
        self.transport.unplug()

    def replug(self) -> None:
        self.transport.replug()

    def stop(self) -> None:
        self.transport.close()
        if self._tmpdir is not None:
            self._tmpdir.cleanup()
            self._tmpdir = None


def start_emulated_station(config: StationConfig, path: str | Path | None = None,
                           motion: MotionSource | None = None, speed: float = 1.0) -> EmulatedStation:
    """One real-time emulated station on a pty; ``path`` is the stable symlink (a temp one if None)."""
    tmpdir = None
    if path is None:
        tmpdir = tempfile.TemporaryDirectory(prefix="courtside-emu-")
        path = Path(tmpdir.name) / f"station{config.station_id}"
    station = BaseStation(config, motion)
    before = time.monotonic()
    link = EmulatorLink(station, realtime=True, speed=speed)
    after = time.monotonic()
    transport = PtyTransport(link, symlink=path)
    return EmulatedStation(station, link, transport, str(path), (before + after) / 2, speed, tmpdir)


def demo_config(index: int, rng: np.random.Generator, **overrides: Any) -> StationConfig:
    """A plausible station: random crystal error within +-100 ppm, random tick register, light radio loss."""
    values: dict[str, Any] = dict(
        station_id=index + 1, serial=0xC0DE0000 + index + 1, seed=index + 1,
        drift_ppm=float(rng.uniform(-100, 100)), tick_offset=int(rng.integers(0, 2**32)),
        radio_loss=0.002, byte_corruption=1e-6,
    )
    values.update(overrides)
    return StationConfig(**values)


def start_emulated_stations(n: int, seed: int = 0, motion_factory: Callable[[int], MotionSource] | None = None,
                            **overrides: Any) -> tuple[list[EmulatedStation], list[str]]:
    """``n`` emulated stations (ids 1..n); returns (handles, paths to open)."""
    rng = np.random.default_rng(seed)
    stations = [start_emulated_station(demo_config(i, rng, **overrides),
                                       motion=motion_factory(i) if motion_factory else None) for i in range(n)]
    return stations, [s.path for s in stations]
