"""The demo's hardware: emulated base stations replaying the performance on real ptys, a synthetic overhead camera
tracked by the gateway's tracker, and the gateway itself — in this process (`demo_hardware`) or in a child
process (`hardware_in_subprocess`, the default for `courtside demo`)."""
from __future__ import annotations

import contextlib
import json
import logging
import select
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from engine.errors import CourtsideError
from firmware_protocol.emulator import StationConfig, TraceSource
from firmware_protocol.emulator.stations import EmulatedStation, start_emulated_station

from engine.mocap import SEED000_SENSORS
from gui.demo.performance import (OPPONENT, OPPONENT_STATION, PLAYER, STATION_SENSORS, Performance, build_opponent,
                                  build_performance)

if TYPE_CHECKING:
    from gateway.court_config import CourtConfig

log = logging.getLogger("courtside.demo")


def start_stations(perf: Performance, opponent: Performance | None = None, rate_hz: int = 100,
                   noise_g: float = 0.02, radio_loss: float = 0.002,
                   drift_ppm: tuple[float, ...] = (35.0, -20.0, 60.0)) -> list[EmulatedStation]:
    """One real-time emulated station per entry of STATION_SENSORS on its own pty, replaying the performance's
    readings (looped), plus the ``opponent``'s station (`OPPONENT_STATION`, the six seed-000 sensors). Ground
    truth for gateway time t is ``perf.pose_at(t - stations[0].wall0_s)`` (the stations start within a
    millisecond of each other)."""
    worn = [(station_id, perf, sensors) for station_id, sensors in STATION_SENSORS.items()]
    if opponent is not None:
        worn.append((OPPONENT_STATION, opponent, SEED000_SENSORS))
    stations = []
    try:
        for k, (station_id, performance, sensors) in enumerate(worn):
            trace = TraceSource(np.stack([performance.acc_g[n] for n in sensors], axis=1), performance.fps)
            config = StationConfig(station_id=station_id, serial=0xC0DE0000 + station_id, n_sensors=len(sensors),
                                   rate_hz=rate_hz, noise_g=noise_g, radio_loss=radio_loss,
                                   drift_ppm=drift_ppm[k % len(drift_ppm)], tick_offset=977_000 * station_id,
                                   seed=station_id, autostart=True)
            stations.append(start_emulated_station(config, motion=trace))
    except Exception:
        for st in stations:
            st.stop()
        raise
    return stations


class DemoCamera:
    """Synthetic overhead camera on the performance, tracked by the gateway's tracker, published to the gateway
    as camera observations (with a JPEG thumbnail and the court->image homography for the overlay). The
    ``opponent`` performs on the other half, as on a real court (without one, a scripted rally stands in for
    him): one track per athlete (`MultiPlayerTracker`, acquired on their own halves), one observation per
    athlete per frame, named ``player`` / ``opponent``.

    Runs as a gateway camera hook (``start(sink)`` / ``stop()``); frames are paced to the wall clock so their
    times line up with the emulated stations' samples. Like a real camera it never delivers a frame more than
    ``MAX_LAG_S`` old: when rendering falls behind the wall clock (a CPU-starved machine) it skips ahead instead of
    publishing seconds-old frames, which the console would get after their synthesis frames were decided."""

    MAX_LAG_S = 0.25

    def __init__(self, perf: Performance, t0_monotonic_s: float, duration_s: float, fps: float = 12.0,
                 image_size: tuple[int, int] = (640, 360), opponent: Performance | None = None) -> None:
        from gateway.camera.court import COURT_KEYPOINTS_M
        from gateway.camera.court_calibration import CourtCalibration
        from gateway.camera.paths import PlayerPath, scripted_rally_path
        from gateway.camera.synthetic import SyntheticCourtCamera, default_court_camera
        from gateway.camera.tracker import MultiPlayerTracker

        self.t0 = t0_monotonic_s
        self.empty_s = 2.5  # empty court first: the tracker learns the background
        t = np.arange(0.0, duration_s + 1.0, 1.0 / perf.fps)

        def ground_path(performance: Performance) -> PlayerPath:
            xy, heading = performance.ground_path(t)
            frames = np.floor(t * performance.fps).astype(int) % performance.n_frames
            standing = np.median(performance.positions_m[:, 0, 1])
            lift = np.clip(performance.positions_m[frames, 0, 1] - standing, 0.0, None)
            return PlayerPath(t + self.empty_s, xy, heading, lift)

        path = ground_path(perf)
        side = "near" if path.xy_m[0, 1] < 0 else "far"
        other_side = "far" if side == "near" else "near"
        other = ground_path(opponent) if opponent is not None else scripted_rally_path(
            duration_s + 1.0, seed=3, side=other_side, start_s=self.empty_s)
        camera = default_court_camera(image_size)
        self.source = SyntheticCourtCamera(path, camera=camera, fps=fps, empty_s=self.empty_s, opponents=[other])
        names = list(COURT_KEYPOINTS_M)
        clicks = camera.project(np.c_[[COURT_KEYPOINTS_M[n] for n in names], np.zeros(len(names))])
        calibration = CourtCalibration.fit(clicks, names=names, image_size=image_size,
                                           camera_matrix=camera.camera_matrix)
        self.tracker = MultiPlayerTracker(calibration, {PLAYER: side, OPPONENT: other_side})
        self.court_to_image = camera.ground_homography()
        self.thumbnail_every = 2
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.frames_published = 0

    def start(self, sink) -> None:
        self._thread = threading.Thread(target=self._run, args=(sink,), name="demo-camera", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)

    def _run(self, sink) -> None:
        import cv2

        from gateway.camera.service import observation

        # path time 0 is the empty-court start; the performance (station time 0) begins empty_s later
        offset = self.t0 - self.empty_s
        while not self._stop.is_set():
            next_s = self.source.next_t_true_s
            if next_s is not None and time.monotonic() - (offset + next_s) > self.MAX_LAG_S:
                self.source.skip_to(time.monotonic() - offset)
            frame = self.source.read()
            if frame is None:
                return
            frame = replace(frame, t_host_s=offset + frame.t_host_s)
            if self._stop.wait(max(0.0, frame.t_host_s - time.monotonic())):
                return
            # thumbnails are the full frame here (scale 1), so the overlay homography is the camera's own
            records = self.tracker.update_all(frame)
            status = self.tracker.status()
            jpeg = None
            if frame.index % self.thumbnail_every == 0:
                ok, data = cv2.imencode(".jpg", frame.image, [cv2.IMWRITE_JPEG_QUALITY, 70])
                jpeg = data.tobytes() if ok else None
            for name, record in records.items():  # the thumbnail rides on the first athlete's observation
                sink(observation(frame, record, self.court_to_image, 1.0, name, status[name]), jpeg)
                jpeg = None
            self.frames_published += 1


def demo_court_config(listen: tuple[str, int], record_dir: Path) -> "CourtConfig":
    """The demo's court as a court config: emulated stations (replaced by the performance-driven ones), two
    ``[[athletes]]`` (the player on stations 1-2, near; the opponent on station 3, far), each with a calibration
    wizard over its worn sites, fast status and clock warm-up for a short demo."""
    from gateway.athletes import AthleteConfig, SensorRef
    from gateway.court_config import CalibrationConfig, CourtConfig, StationsConfig

    player = [(SensorRef("st", sid, i), name) for sid, names in STATION_SENSORS.items() for i, name in enumerate(names)]
    opponent = [(SensorRef("st", OPPONENT_STATION, i), name) for i, name in enumerate(SEED000_SENSORS)]
    athletes = tuple(AthleteConfig(name, side, tuple(r for r, _ in worn), tuple(n for _, n in worn))
                     for name, side, worn in ((PLAYER, "near", player), (OPPONENT, "far", opponent)))
    return CourtConfig(listen=listen, record_dir=record_dir, name="courtside-demo", status_interval_s=0.5,
                       clock_lock_after_s=5.0, stations=StationsConfig(emulate=len(STATION_SENSORS) + 1),
                       calibration=CalibrationConfig(pose="npose", records_dir=record_dir / "calibrations"),
                       athletes=athletes)


@contextlib.contextmanager
def demo_hardware(listen: tuple[str, int], record_dir: Path, camera: bool,
                  duration_s: float | None) -> Iterator[tuple[tuple[str, int], float]]:
    """Stations + camera + gateway in THIS process; yields (gateway address, performance start time). The
    gateway is built by the same loader as `courtside gateway --config` (gateway.assembly); only the emulated
    stations and the camera are the demo's own (they replay the performance)."""
    from gateway.assembly import build_court

    perf, opponent = build_performance(), build_opponent()
    with contextlib.ExitStack() as stack:
        stations = start_stations(perf, opponent)
        for st in stations:
            stack.callback(st.stop)
        t0 = stations[0].wall0_s
        cam = DemoCamera(perf, t0, (duration_s or 3600.0) + 5.0, opponent=opponent) if camera else None
        try:
            court = build_court(demo_court_config(listen, record_dir), camera=cam, emulators=stations)
        except OSError as exc:  # e.g. the address is taken by another demo or gateway: one line, not a traceback
            where = f" ({exc.filename})" if exc.filename else ""
            raise CourtsideError(f"the demo gateway cannot start on {listen[0]}:{listen[1]}: "
                                 f"{exc.strerror or exc}{where}") from None
        stack.callback(court.gateway.stop)
        announcer = TruthAnnouncer(court.gateway, perf.clip_names, t0)
        announcer.start()
        stack.callback(announcer.stop)
        yield court.address, t0


class TruthAnnouncer(threading.Thread):
    """Stamps every take recorded during the demo with what its ground truth is: when a recording starts, one
    gateway event carrying ``truth_clips`` and ``truth_t0_s`` (recorded with the take), so playing the take back
    later — in any console — can draw the true skeleton beside the synthesized one (`truth_from_events`)."""

    def __init__(self, gateway, clip_names: tuple[str, ...], t0_s: float) -> None:
        super().__init__(name="demo-truth", daemon=True)
        self.gateway, self.clip_names, self.t0_s = gateway, clip_names, t0_s
        self._stop_event = threading.Event()

    def run(self) -> None:
        was_active = False
        while not self._stop_event.wait(0.1):
            active = self.gateway.recorder.active
            if active and not was_active:
                self.gateway.publish_event("info", "demo", "ground truth for this take: held-out CMU clips "
                                           + ", ".join(self.clip_names),
                                           {"truth_clips": list(self.clip_names), "truth_t0_s": self.t0_s})
            was_active = active

    def stop(self) -> None:
        self._stop_event.set()
        self.join(timeout=2)


def hardware_main(argv: list[str]) -> int:
    """``python -m gui.demo LISTEN_HOST LISTEN_PORT RECORD_DIR CAMERA(0|1) DURATION_S|-``: run the demo hardware,
    print ``{"address": [host, port], "t0": s}`` as one JSON line when ready, stop when stdin closes. If it cannot
    start (a refused config, the address in use) it prints ``{"error": "..."}`` instead and exits 1, so the
    console reports one line rather than two tracebacks."""
    host, port, record_dir, camera, duration = argv
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        with demo_hardware((host, int(port)), Path(record_dir), camera == "1",
                           None if duration == "-" else float(duration)) as (address, t0):
            print(json.dumps({"address": list(address), "t0": t0}), flush=True)
            sys.stdin.read()  # until the console closes our stdin (or dies, which closes it too)
    except CourtsideError as exc:  # not started: say why on the pipe the parent reads
        print(json.dumps({"error": str(exc)}), flush=True)
        return 1
    return 0


@contextlib.contextmanager
def hardware_in_subprocess(listen: tuple[str, int], record_dir: Path, camera: bool,
                           duration_s: float | None) -> Iterator[tuple[tuple[str, int], float]]:
    """The same hardware in a child process, so the console's GUI thread never shares a GIL with the station
    readers, emulators and camera renderer (on 2 cores this alone roughly triples the console's frame rate).
    CLOCK_MONOTONIC is system-wide, so the child's gateway times are directly comparable here. A plain
    subprocess rather than multiprocessing: nothing depends on how the parent's main module was started."""
    args = [sys.executable, "-m", "gui.demo", listen[0], str(listen[1]), str(Path(record_dir).resolve()),
            "1" if camera else "0", "-" if duration_s is None else str(duration_s)]
    proc = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 120.0)
        line = proc.stdout.readline() if ready else ""
        if not line:
            raise CourtsideError(f"the demo hardware process did not start (exit code {proc.poll()})")
        info = json.loads(line)
        if "error" in info:
            raise CourtsideError(info["error"])
        yield (info["address"][0], int(info["address"][1])), float(info["t0"])
    finally:
        try:
            proc.stdin.close()
        except OSError:
            pass
        try:
            proc.wait(15.0)
        except subprocess.TimeoutExpired:
            proc.terminate()
            proc.wait(5.0)
