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

from firmware_protocol.emulator import BaseStation, MotionSource, StationConfig, TraceSource
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


def worn_sensor_sites(index: int) -> tuple[str, ...]:
    """Standard sensor sites worn on emulated station ``index`` (0-based) when replaying mocap: the first
    station carries the engine's six seed-000 sensors (what the console synthesises from by default), the
    next the other standard sites, and so on alternately."""
    from engine.mocap import SEED000_SENSORS, STANDARD_SENSORS

    others = tuple(s for s in STANDARD_SENSORS if s not in SEED000_SENSORS)
    return tuple(SEED000_SENSORS) if index % 2 == 0 else others


def mocap_traces(clips: tuple[str | Path, ...], worn: list[tuple[str, ...]], fps: float = 60.0,
                 orientation_seed: int | None = None) -> list[TraceSource]:
    """Virtual accelerometer traces of ``clips`` played back to back (each clip on its own skeleton), one trace
    per station with its ``worn`` sites; ``clips`` are shipped clip names or .bvh/.amc paths, () = every
    shipped clip. Raises CourtsideError naming a clip that is neither. With ``orientation_seed`` the traces also
    carry what each sensor's fusion filter and gyroscope report: `OrientationErrorModel.realistic()` (seeded) on
    the virtual orientations of the whole concatenated trace (one yaw offset and drift per sensor across clips)
    and `virtual_gyroscopes`."""
    from engine.errors import CourtsideError
    from engine.mocap import load_clip, sample_clips, standard_placements, virtual_accelerometers, virtual_gyroscopes
    from engine.mocap.orientation import OrientationErrorModel, virtual_orientations

    shipped = sample_clips()
    paths = []
    for clip in clips or tuple(shipped):
        if str(clip) in shipped:
            paths.append(shipped[str(clip)])
        elif Path(clip).is_file():
            paths.append(Path(clip))
        else:
            raise CourtsideError(f"emulated motion: {clip}: no such file, and not a shipped clip "
                                 f"({', '.join(sorted(shipped))})")
    sites = sorted({s for w in worn for s in w})
    acc_parts, quat_parts, gyro_parts = [], [], []
    for path in paths:
        motion = load_clip(path, fps=fps)
        placements = standard_placements(motion.skeleton, sites)
        acc_parts.append(virtual_accelerometers(motion, placements))
        if orientation_seed is not None:
            quat_parts.append(virtual_orientations(motion, placements))
            gyro_parts.append(virtual_gyroscopes(motion, placements))
    acc = np.concatenate(acc_parts)  # (F, sites, 3)
    quat = gyro = None
    if orientation_seed is not None:
        quat = OrientationErrorModel.realistic().apply(np.concatenate(quat_parts), fps,
                                                       np.random.default_rng(orientation_seed))
        gyro = np.concatenate(gyro_parts)
    columns = [[sites.index(s) for s in w] for w in worn]
    return [TraceSource(acc[:, c], fps, None if quat is None else quat[:, c], None if gyro is None else gyro[:, c])
            for c in columns]


def start_court_stations(n: int, motion: str = "mocap", clips: tuple[str | Path, ...] = (), seed: int = 0,
                         orientation: bool = False) -> tuple[list[EmulatedStation], list[str]]:
    """``n`` emulated stations for `courtside gateway --emulate N`: with ``motion="mocap"`` they replay mocap
    clips as worn accelerometers (`worn_sensor_sites`, `mocap_traces`), so a console shows a moving skeleton;
    ``"none"`` gives the emulator's still sensors. ``orientation``: the stations speak protocol v2 and also
    stream each sensor's orientation (realistic filter error) and angular rate."""
    if motion == "mocap":
        worn = [worn_sensor_sites(i) for i in range(n)]
        traces = mocap_traces(clips, worn, orientation_seed=seed if orientation else None)
        rng = np.random.default_rng(seed)
        stations: list[EmulatedStation] = []
        try:
            for i, trace in enumerate(traces):
                stations.append(start_emulated_station(
                    demo_config(i, rng, n_sensors=trace.n_sensors, orientation=orientation), motion=trace))
        except Exception:
            for st in stations:
                st.stop()
            raise
        return stations, [s.path for s in stations]
    return start_emulated_stations(n, seed=seed, orientation=orientation)
