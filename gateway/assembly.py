"""Build a whole court from one `CourtConfig`: emulated stations, camera + tracker, calibration wizard, secrets
and the `Gateway` — what `courtside gateway --config` runs and what `courtside demo` builds its gateway with.

Why one builder: before, only the demo wired a camera and a calibration wizard (by hand, in gui/), so a real
daemon on the court's board had neither (issue 13). Everything that can be refused (secrets, camera, court
calibration, clips) is opened *before* anything starts, so a bad config stops with one line and no leftovers.
"""
from __future__ import annotations

import contextlib
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from engine.errors import CourtsideError
from gateway import auth
from gateway.athletes import DEFAULT_ATHLETE, AthleteConfig, AthleteMap
from gateway.court_config import CameraConfig, CourtConfig, check_consistent
from gateway.daemon.core import Gateway
from gateway.names import free_name
from gateway.server import RequestError

if TYPE_CHECKING:
    from firmware_protocol.emulator.stations import EmulatedStation

log = logging.getLogger("gateway")


class StartError(CourtsideError, OSError):
    """Something the config rightly asks for cannot be done now: a live camera unplugged, busy or not ready, the
    first take not startable (disk full). Unlike a bad config, a restart may fix it, so the CLI exits 1
    (docs/gateway.md "Exit codes")."""


@dataclass
class Court:
    """A running court. ``stop()`` stops the gateway (recording flushed), then camera and emulators."""

    config: CourtConfig
    gateway: Gateway
    emulators: list[EmulatedStation] = field(default_factory=list)
    take: str | None = None  # the take recording started with (suffixed if ``config.record`` existed)

    @property
    def address(self) -> tuple[str, int]:
        return self.gateway.address

    def stop(self) -> None:
        try:
            self.gateway.stop()
        finally:
            for emulator in self.emulators:
                emulator.stop()

    def __enter__(self) -> "Court":
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def is_video_file(source: int | str) -> bool:
    """A camera source that is a regular file is a video file (played paced, like a live camera)."""
    return isinstance(source, str) and Path(source).is_file()


def build_camera(config: CameraConfig, athletes: tuple[AthleteConfig, ...] = ()) -> Any:
    """Open the configured camera and its court calibration, with one track per athlete (default: the single
    athlete, acquired on ``config.player_side``); `CourtsideError` names what failed."""
    import cv2

    from gateway.camera.court_calibration import CourtCalibration
    from gateway.camera.errors import CameraError
    from gateway.camera.service import CameraService
    from gateway.camera.sources import OpenCVCamera, VideoFileSource
    from gateway.camera.tracker import MultiPlayerTracker, TrackerConfig

    assert config.source is not None and config.court is not None
    # One OpenCV thread: the camera thread's per-frame work is a few ms, and a pool fanned out over the board's
    # cores costs more CPU in hand-offs than it saves in latency (and competes with the stations' threads).
    cv2.setNumThreads(1)
    try:
        calibration = CourtCalibration.load(config.court)
        if is_video_file(config.source):
            source: Any = VideoFileSource(config.source)
            realtime, label = True, f"file {config.source}"
        else:
            try:
                source = OpenCVCamera(config.source, fps=config.fps, latency_s=config.latency_s)
            except CameraError as exc:
                raise StartError(f"camera: {exc}") from None
            realtime, label = False, f"camera {config.source}"
    except CameraError as exc:
        raise CourtsideError(f"camera: {exc}") from None
    if tuple(source.image_size) != tuple(calibration.image_size):
        source.close()
        raise CourtsideError(f"camera: {label} gives {source.image_size[0]}x{source.image_size[1]} px frames but "
                             f"the court calibration {config.court} was made for "
                             f"{calibration.image_size[0]}x{calibration.image_size[1]} px")
    sides = {a.name: a.side for a in athletes} or {DEFAULT_ATHLETE: config.player_side}
    tracker = MultiPlayerTracker(calibration, sides, TrackerConfig())
    return CameraService(source, tracker, realtime=realtime, thumbnail_every=config.thumbnail_every,
                         loop=config.loop, label=label)


def build_calibration(config: CourtConfig) -> Any:
    """One calibration wizard per athlete over its sensor sites (`gateway.calibration.athletes`), or None when
    no athlete names any. Every athlete's records go to ``calibration.records_dir`` with the same pose."""
    cal = config.calibration
    athletes = [a for a in config.effective_athletes() if a.placements]
    if not athletes:
        return None
    from gateway.calibration.athletes import AthleteCalibrations
    from gateway.calibration.service import CalibrationService

    return AthleteCalibrations({a.name: CalibrationService.standard(a.placements, pose=cal.pose,
                                                                    records_dir=cal.records_dir)
                                for a in athletes})


def build_court(config: CourtConfig, *, status_line: Callable[[str], None] | None = None, camera: Any = None,
                calibration: Any = None, emulators: list[EmulatedStation] | None = None,
                gateway_options: dict[str, Any] | None = None) -> Court:
    """Start everything ``config`` describes and return the running `Court`.

    ``camera`` / ``calibration`` / ``emulators`` replace what the config would build (the demo passes its
    performance-driven stations and camera); the gateway itself is always built here. The rules across keys
    are checked here too, so a config built in code (the demo's) cannot listen beyond loopback unauthenticated."""
    check_consistent(config)
    secrets = auth.Secrets.from_files(config.auth.operator_secret_file, config.auth.viewer_secret_file)
    tls = auth.server_tls_context(config.auth.tls_cert, config.auth.tls_key) if config.auth.tls_cert else None
    if camera is None and config.camera.source is not None:
        camera = build_camera(config.camera, config.athletes)
    if calibration is None:
        calibration = build_calibration(config)
    started: list[EmulatedStation] = []
    if emulators is None and config.stations.emulate:
        from firmware_protocol.emulator.stations import start_court_stations  # the emulator only when asked for

        try:
            if config.athletes and config.stations.emulate_motion == "mocap":
                started = start_athlete_stations(config)
            else:
                started, _ = start_court_stations(config.stations.emulate, config.stations.emulate_motion,
                                                  config.stations.emulate_clips,
                                                  orientation=config.stations.emulate_orientation)
        except Exception:
            if camera is not None:
                camera.source.close()
            raise
        emulators = started
    emulators = list(emulators or [])
    sources = [*config.stations.ports, *config.stations.urls, *(e.path for e in emulators)]
    if not sources and not config.stations.discover:
        log.warning("no stations configured (ports, urls, emulate or discover)")
    options = dict(listen=config.listen, record_dir=config.record_dir, camera=camera, calibration=calibration,
                   status_interval_s=config.status_interval_s, lock_after_s=config.clock_lock_after_s,
                   status_line=status_line, discover=config.stations.discover, name=config.name, secrets=secrets,
                   max_clients=config.max_clients, handshake_timeout_s=config.handshake_timeout_s, tls=tls,
                   athletes=AthleteMap(config.effective_athletes()))
    if config.lsl.enabled:
        from gateway.lsl import LslPublisher

        options["sample_sinks"] = (LslPublisher(config.name, config.lsl.scope).on_block,)
    options.update(gateway_options or {})
    try:
        gateway = Gateway(sources, **options).start()
    except BaseException:
        for emulator in started:
            emulator.stop()
        if camera is not None and hasattr(camera, "source"):
            camera.source.close()
        raise
    court = Court(config, gateway, emulators)
    if config.record:
        try:
            court.take = start_recording_fresh(gateway, config.record)
        except RequestError as exc:
            court.stop()
            raise StartError(f"cannot start recording: {exc}") from None
        except BaseException:
            court.stop()
            raise
    return court


def athlete_station_motion(config: CourtConfig, station_id: int) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(worn sites by sensor index, clips) that emulated station ``station_id`` replays: the sites and clips of
    the athlete wearing its sensors (``"st<id>:<i>"``; sites from the athlete's placements, else the engine's six
    seed-000 sensors), else the default station's."""
    from firmware_protocol.emulator.stations import worn_sensor_sites

    for athlete in config.athletes:
        refs = sorted((ref.index, k) for k, ref in enumerate(athlete.sensors)
                      if ref.key == "st" and ref.station == station_id)
        if refs:
            sites = worn_sensor_sites(0)
            worn = tuple(athlete.placements[k] if athlete.placements else sites[i % len(sites)] for i, k in refs)
            return worn, athlete.clips or config.stations.emulate_clips
    return worn_sensor_sites(station_id - 1), config.stations.emulate_clips


def start_athlete_stations(config: CourtConfig, seed: int = 0) -> list[EmulatedStation]:
    """``stations.emulate`` emulated stations (ids 1..n) each replaying its athlete's clips on its athlete's
    worn sites (`athlete_station_motion`): two athletes moving differently, each on their own sensors. With
    ``stations.emulate_orientation`` they also stream orientation and angular rate (protocol v2)."""
    import numpy as np

    from firmware_protocol.emulator.stations import demo_config, mocap_traces, start_emulated_station

    orientation = config.stations.emulate_orientation
    rng = np.random.default_rng(seed)
    stations: list[EmulatedStation] = []
    with contextlib.ExitStack() as undo:  # a failure part-way stops the stations already started
        for i in range(config.stations.emulate):
            worn, clips = athlete_station_motion(config, i + 1)
            (trace,) = mocap_traces(clips, [worn], orientation_seed=seed + i if orientation else None)
            station = start_emulated_station(demo_config(i, rng, n_sensors=trace.n_sensors, orientation=orientation),
                                             motion=trace)
            undo.callback(station.stop)
            stations.append(station)
        undo.pop_all()
    return stations


def start_recording_fresh(gateway: Gateway, take: str) -> str:
    """Start recording ``take``, or ``take-2``, ``take-3``... if it exists: a daemon restarted by its service
    manager with the same ``--record`` continues into a new take instead of refusing (issue 13)."""
    record_dir = Path(gateway.recorder.record_dir)
    name = free_name(take, lambda candidate: (record_dir / candidate).exists())
    if name != take:
        gateway.publish_event("warning", "recorder", f"take {take!r} exists (a restart?); recording {name!r}")
    gateway.handle_request("start_recording", {"take": name})
    return name
