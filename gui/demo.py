"""The live demo scenario: real mocap replayed as body-worn accelerometers on emulated base stations, a synthetic
overhead camera, and the in-process gateway — everything `courtside demo` starts before opening the console.

A "performance" is a few shipped CMU clips that the motion graph does NOT contain (held out), played back to back
on the court and looped. Every worn sensor reads the performance's virtual accelerometer; the same frames give the
ground-truth skeleton drawn beside the synthesized one, so the operator sees how well the engine follows."""
from __future__ import annotations

import contextlib
import json
import logging
import math
import select
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from engine.mocap import SEED000_SENSORS, Skeleton, forward_kinematics, load_clip, root_heading, sample_clips, standard_placements, virtual_accelerometers
from firmware_protocol.emulator import StationConfig, TraceSource
from gateway.emulated import EmulatedStation, start_emulated_station

from gui.engine_link import GRAPH_FPS

HELD_OUT_CLIPS = ("16_32", "16_36", "16_05")  # walk, run, forward jump: not in the demo's motion graph
EXTRA_SENSORS = ("left_wrist", "right_wrist", "left_ankle", "right_ankle", "right_foot")
STATION_SENSORS = {1: SEED000_SENSORS, 2: EXTRA_SENSORS}  # station id -> worn sensors, in sensor-index order
COURT_START_M = np.array([-5.0, -10.0])  # court (x, y) where the performance starts: inside the near baseline


@dataclass
class Performance:
    """Held-out clips back to back, placed on the court, played in a loop that never teleports.

    Pass 0 plays the frames as placed (start S -> end E along the baseline); pass 1 plays the same frames turned
    180 degrees about the midpoint of S and E, so it runs E -> S; and so on. A rigid turn leaves every worn
    sensor's reading unchanged, so the stations simply loop the readings while the body shuttles along the
    baseline — and the overhead camera's tracker never sees a jump."""

    fps: float
    positions_m: np.ndarray  # (F, J, 3) pass-0 world positions (X, Y up, Z) with (X, Z) = court (x, y)
    heading_rad: np.ndarray  # (F,) pass-0 root heading
    acc_g: dict[str, np.ndarray]  # sensor name -> (F, 3) virtual accelerometer reading, sensor frame
    skeleton: Skeleton
    clip_names: tuple[str, ...]

    @property
    def parents(self) -> np.ndarray:
        return np.asarray(self.skeleton.parents)

    @property
    def n_frames(self) -> int:
        return len(self.positions_m)

    def _frames(self, t_s: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        k = np.floor(np.asarray(t_s, float) * self.fps).astype(int)
        return k % self.n_frames, (k // self.n_frames) % 2 == 1

    def pose_at(self, t_s: float) -> np.ndarray:
        """(J, 3) joint positions ``t_s`` seconds after the performance started."""
        frame, turned = self._frames(t_s)
        pos = self.positions_m[int(frame)].copy()
        if turned:
            pivot2 = self.positions_m[0, 0, [0, 2]] + self.positions_m[-1, 0, [0, 2]]
            pos[:, [0, 2]] = pivot2 - pos[:, [0, 2]]
        return pos

    def ground_path(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Root court (x, y) (N, 2) and heading (N,) at times ``t_s``: what the overhead camera should see."""
        frame, turned = self._frames(t_s)
        xy = self.positions_m[frame, 0][:, [0, 2]]
        pivot2 = self.positions_m[0, 0, [0, 2]] + self.positions_m[-1, 0, [0, 2]]
        xy = np.where(turned[:, None], pivot2 - xy, xy)
        heading = np.angle(np.exp(1j * (self.heading_rad[frame] + np.where(turned, np.pi, 0.0))))
        return xy, heading


def build_performance(clip_names: tuple[str, ...] = HELD_OUT_CLIPS, fps: float = GRAPH_FPS) -> Performance:
    """Chain the clips: each starts where the previous one ended (ground position), all on one skeleton."""
    clips = sample_clips()
    missing = [c for c in clip_names if c not in clips]
    if missing:
        raise ValueError(f"unknown clip(s) {missing}; shipped: {sorted(clips)}")
    names = sorted({n for sensors in STATION_SENSORS.values() for n in sensors})
    positions, accs = [], {n: [] for n in names}
    cursor = COURT_START_M.copy()
    for name in clip_names:
        motion = load_clip(clips[name], fps=fps)
        pos, glob = forward_kinematics(motion)
        acc = virtual_accelerometers(motion, standard_placements(motion.skeleton, tuple(names)), fk=(pos, glob))
        pos = pos.copy()
        pos[..., 0] += cursor[0] - pos[0, 0, 0]
        pos[..., 2] += cursor[1] - pos[0, 0, 2]
        cursor = pos[-1, 0, [0, 2]]
        positions.append(pos)
        for k, n in enumerate(names):
            accs[n].append(acc[:, k])
        skeleton = motion.skeleton
    pos = along_baseline(np.concatenate(positions), COURT_START_M)
    heading = np.concatenate([root_heading(load_clip(clips[c], fps=fps), p)
                              for c, p in zip(clip_names, np.split(pos, np.cumsum([len(p) for p in positions])[:-1]))])
    return Performance(fps, pos, heading, {n: np.concatenate(v) for n, v in accs.items()}, skeleton,
                       tuple(clip_names))


def along_baseline(positions_m: np.ndarray, start_m: np.ndarray) -> np.ndarray:
    """Turn the whole performance about its start so it travels along +X (parallel to the baseline), as a
    baseline rally does; the accelerometers are unaffected (they read in the sensor frame)."""
    root = positions_m[:, 0, [0, 2]]
    dx, dz = root[-1] - root[0]
    beta = math.pi / 2 - math.atan2(dx, dz)  # heading rotation that takes the travel direction onto +X
    c, s = math.cos(beta), math.sin(beta)
    rel = positions_m[..., [0, 2]] - root[0]
    out = positions_m.copy()
    out[..., 0] = start_m[0] + rel[..., 0] * c + rel[..., 1] * s
    out[..., 2] = start_m[1] - rel[..., 0] * s + rel[..., 1] * c
    return out


def start_stations(perf: Performance, rate_hz: int = 100, noise_g: float = 0.02, radio_loss: float = 0.002,
                   drift_ppm: tuple[float, ...] = (35.0, -20.0)) -> list[EmulatedStation]:
    """One real-time emulated station per entry of STATION_SENSORS on its own pty, replaying the performance's
    readings (looped). Ground truth for gateway time t is ``perf.pose_at(t - stations[0].wall0_s)`` (the
    stations start within a millisecond of each other)."""
    stations = []
    try:
        for k, (station_id, sensors) in enumerate(STATION_SENSORS.items()):
            trace = TraceSource(np.stack([perf.acc_g[n] for n in sensors], axis=1), perf.fps)
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


def placements_for_demo(perf: Performance) -> list:
    """Standard placements of every worn demo sensor (the calibration wizard's segments)."""
    return standard_placements(perf.skeleton, tuple(n for names in STATION_SENSORS.values() for n in names))


def sensor_segments() -> dict[tuple[str, int], str]:
    """(station, sensor) -> worn placement name, for the device panel's body diagram and the recording gate."""
    return {(f"st{sid}", i): name for sid, names in STATION_SENSORS.items() for i, name in enumerate(names)}


def synthesis_sensors() -> list[tuple[str, int]]:
    """Live sensors feeding the graph's sensors (SEED000 order), all on station 1."""
    return [("st1", i) for i in range(len(SEED000_SENSORS))]


class TruthClock:
    """Ground truth for the console: gateway time -> performance joint positions (looped)."""

    def __init__(self, perf: Performance, t0_monotonic_s: float) -> None:
        self.perf = perf
        self.t0 = t0_monotonic_s

    def __call__(self, t_host_s: float) -> np.ndarray | None:
        if t_host_s < self.t0:
            return None
        return self.perf.pose_at(t_host_s - self.t0)


class DemoCamera:
    """Synthetic overhead camera on the performance, tracked by the gateway's player tracker, published to the
    gateway as camera observations (with a JPEG thumbnail and the court->image homography for the overlay).

    Runs as a gateway camera hook (``start(sink)`` / ``stop()``); frames are paced to the wall clock so their
    times line up with the emulated stations' samples."""

    def __init__(self, perf: Performance, t0_monotonic_s: float, duration_s: float, fps: float = 12.0,
                 image_size: tuple[int, int] = (640, 360)) -> None:
        from gateway.camera.court import COURT_KEYPOINTS_M
        from gateway.camera.court_calibration import CourtCalibration
        from gateway.camera.paths import PlayerPath
        from gateway.camera.synthetic import SyntheticCourtCamera, default_court_camera
        from gateway.camera.tracker import PlayerTracker

        self.t0 = t0_monotonic_s
        self.empty_s = 2.5  # empty court first: the tracker learns the background
        t = np.arange(0.0, duration_s + 1.0, 1.0 / perf.fps)
        xy, heading = perf.ground_path(t)
        frames = np.floor(t * perf.fps).astype(int) % perf.n_frames
        lift = np.clip(perf.positions_m[frames, 0, 1] - np.median(perf.positions_m[:, 0, 1]), 0.0, None)
        path = PlayerPath(t + self.empty_s, xy, heading, lift)
        camera = default_court_camera(image_size)
        self.source = SyntheticCourtCamera(path, camera=camera, fps=fps, empty_s=self.empty_s)
        names = list(COURT_KEYPOINTS_M)
        clicks = camera.project(np.c_[[COURT_KEYPOINTS_M[n] for n in names], np.zeros(len(names))])
        calibration = CourtCalibration.fit(clicks, names=names, image_size=image_size,
                                           camera_matrix=camera.camera_matrix)
        self.tracker = PlayerTracker(calibration)
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
            frame = self.source.read()
            if frame is None:
                return
            frame = replace(frame, t_host_s=offset + frame.t_host_s)
            if self._stop.wait(max(0.0, frame.t_host_s - time.monotonic())):
                return
            # thumbnails are the full frame here (scale 1), so the overlay homography is the camera's own
            obs = observation(frame, self.tracker.update(frame), self.court_to_image, 1.0)
            jpeg = None
            if frame.index % self.thumbnail_every == 0:
                ok, data = cv2.imencode(".jpg", frame.image, [cv2.IMWRITE_JPEG_QUALITY, 70])
                jpeg = data.tobytes() if ok else None
            sink(obs, jpeg)
            self.frames_published += 1


log = logging.getLogger("courtside.demo")


@contextlib.contextmanager
def demo_hardware(listen: tuple[str, int], record_dir: Path, camera: bool,
                  duration_s: float | None) -> Iterator[tuple[tuple[str, int], float]]:
    """Stations + camera + gateway in THIS process; yields (gateway address, performance start time)."""
    from gateway.calibration.service import CalibrationService
    from gateway.calibration.wizard import segment_specs_from_placements
    from gateway.daemon import Gateway

    perf = build_performance()
    with contextlib.ExitStack() as stack:
        stations = start_stations(perf)
        for st in stations:
            stack.callback(st.stop)
        t0 = stations[0].wall0_s
        cam = DemoCamera(perf, t0, (duration_s or 3600.0) + 5.0) if camera else None
        specs = segment_specs_from_placements(placements_for_demo(perf))
        gateway = Gateway([st.path for st in stations], listen=listen, record_dir=record_dir, camera=cam,
                          calibration=CalibrationService(specs), status_interval_s=0.5, lock_after_s=5.0,
                          name="courtside-demo")
        gateway.start()
        stack.callback(gateway.stop)
        announcer = TruthAnnouncer(gateway, perf.clip_names, t0)
        announcer.start()
        stack.callback(announcer.stop)
        yield gateway.address, t0


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


def truth_from_events(events: list[dict]) -> TruthClock | None:
    """Ground truth of a recorded demo take, from the `TruthAnnouncer` event it carries (None if absent)."""
    for header in events:
        if "truth_clips" in header and "truth_t0_s" in header:
            perf = build_performance(tuple(header["truth_clips"]))
            return TruthClock(perf, float(header["truth_t0_s"]))
    return None


def hardware_main(argv: list[str]) -> int:
    """``python -m gui.demo LISTEN_HOST LISTEN_PORT RECORD_DIR CAMERA(0|1) DURATION_S|-``: run the demo hardware,
    print ``{"address": [host, port], "t0": s}`` as one JSON line when ready, stop when stdin closes."""
    host, port, record_dir, camera, duration = argv
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    with demo_hardware((host, int(port)), Path(record_dir), camera == "1",
                       None if duration == "-" else float(duration)) as (address, t0):
        print(json.dumps({"address": list(address), "t0": t0}), flush=True)
        sys.stdin.read()  # until the console closes our stdin (or dies, which closes it too)
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
            raise RuntimeError(f"demo hardware process did not start (exit code {proc.poll()})")
        info = json.loads(line)
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

    from gui.engine_link import load_or_build_graph, sensor_joints, synthesis_setup
    from gui.main_window import ConsoleWindow

    hardware = hardware_in_subprocess if separate_process else demo_hardware
    perf = build_performance()  # deterministic: the same frames the stations replay, for ground truth here
    graph, skeleton, cache = load_or_build_graph(exclude=perf.clip_names)
    log.info("motion graph %s: %d nodes from the shipped clips minus held-out %s", cache, graph.n_nodes,
             ", ".join(perf.clip_names))
    with contextlib.ExitStack() as stack:
        address, t0 = stack.enter_context(hardware(listen, record_dir, camera, duration_s))
        client = GatewayClient(*address).connect()
        stack.callback(client.close)
        log.info("demo gateway on %s:%d (connect more consoles with `courtside console --connect ...`)", *address)
        window = ConsoleWindow(client, synthesis=synthesis_setup(graph, skeleton, synthesis_sensors(), lag_s),
                               truth=TruthClock(perf, t0), sensor_segments=sensor_segments(),
                               sensor_joints=sensor_joints(skeleton, sensor_segments()),
                               title="Courtside demo — emulated stations replaying held-out CMU mocap")
        stack.callback(window.shutdown)
        window.resize(1500, 950)
        yield DemoSession(perf, address, client, window)


if __name__ == "__main__":
    sys.exit(hardware_main(sys.argv[1:]))
