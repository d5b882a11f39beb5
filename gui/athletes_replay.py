"""Two athletes through the console's per-athlete path, without a window (issue 20).

The console decides who is synthesised from the gateway's hello (`athlete_stations`: athlete -> the station of
its first sensor), builds one synthesis per athlete and lets one `gui.bridge.GatewayBridge` route the stream:
every sample block goes to every synthesis (each takes only its own sensors) and each camera observation only
to its athlete's synthesis. `synthesize_athletes` runs exactly that routing on a message list and finishes each
synthesis, so a test or bench can check that per-athlete poses equal the poses of the same take run alone (the
engines share no state: they must be equal bit for bit).
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from engine.evaluation import simulate
from engine.evaluation.takes import Take
from engine.mocap import SensorErrorModel
from engine.mocap.orientation import OrientationErrorModel
from engine.stream.session import FramePose, RecordedStreams, StreamSynthesis
from gateway.codec import Message

from gui.bridge import GatewayBridge
from gui.ringbuffer import TraceStore
from gui.synthesis import SynthesisSetup


def athlete_stations(hello_athletes: Sequence[dict] | None, stations: list[dict]) -> dict[str, str]:
    """Athlete -> the station carrying its first sensor, from the gateway's hello (`gateway.athletes.athletes_info`):
    ``"st<id>:<i>"`` names the station directly, ``"sn<serial>:<i>"`` through the stations' HELLO serials.
    Athletes without sensors (the single default athlete) are left out."""
    out = {}
    serials = {s.get("station_serial"): str(s["station"]) for s in stations if s.get("station_serial") is not None}
    for athlete in hello_athletes or []:
        if not athlete.get("sensors"):
            continue
        ref = str(athlete["sensors"][0]).split(":")[0]
        station = ref if ref.startswith("st") else serials.get(int(ref[2:], 0))
        if station is not None:
            out[str(athlete["name"])] = station
    return out


@dataclass
class SimulatedAthlete:
    """One athlete's held-out take as its station and the camera would stream it: ``streams`` the raw inputs
    (keyed ``(station, sensor)``, on the gateway clock: take time + ``offset_s``) and ``messages`` the same data as
    the gateway's tagged messages."""

    name: str
    station: str
    take: Take
    offset_s: float
    streams: RecordedStreams
    messages: list[Message]


def simulate_athlete(name: str, station: str, take: Take, sensor_names: Sequence[str], offset_s: float,
                     seed: int, rate_hz: float = 100.0) -> SimulatedAthlete:
    """The take's worn sensors at ``rate_hz`` (accelerations with the measured real error model, device-earth
    orientations with the realistic filter errors) and the camera's 30 Hz fixes (5 cm / 10 deg), one draw per
    ``seed``."""
    rng = np.random.default_rng(seed)
    acc, times = simulate.accelerometers(take, sensor_names, SensorErrorModel.measured_real(), rng, fps=rate_hz)
    quat = simulate.orientations(take, sensor_names, OrientationErrorModel.realistic(), rng, fps=rate_hz)
    cam = simulate.camera_track(take, simulate.CameraModel(), rng)
    fixes = np.flatnonzero(np.isfinite(cam.heading_rad))
    t_s, cam_t_s = times + offset_s, fixes / take.fps + offset_s
    streams = RecordedStreams({(station, k): (t_s, acc[:, k], quat[:, k]) for k in range(acc.shape[1])},
                              [(float(t), cam.position_m[i], float(cam.heading_rad[i]))
                               for t, i in zip(cam_t_s, fixes)])
    messages = in_stream_order(sample_messages(station, name, t_s, acc, quat),
                               camera_messages(name, cam_t_s, cam.position_m[fixes], cam.heading_rad[fixes]))
    return SimulatedAthlete(name, station, take, offset_s, streams, messages)


def sample_messages(station: str, athlete: str, t_s: np.ndarray, acc_g: np.ndarray,
                    quat_wxyz: np.ndarray | None = None, block: int = 10) -> list[Message]:
    """One station's (T, S, ...) readings as the gateway streams them: per sensor, blocks of ``block`` samples
    tagged with the wearer."""
    out = []
    for k in range(acc_g.shape[1]):
        for i in range(0, len(t_s), block):
            arrays = {"t_host_s": t_s[i:i + block], "acc_g": acc_g[i:i + block, k]}
            if quat_wxyz is not None:
                arrays["quat_wxyz"] = quat_wxyz[i:i + block, k]
            out.append(Message("samples", {"station": station, "sensor": k, "athlete": athlete,
                                           "t_host_s": float(t_s[min(i + block, len(t_s)) - 1])}, arrays))
    return out


def camera_messages(athlete: str, t_s: np.ndarray, position_m: np.ndarray, heading_rad: np.ndarray) -> list[Message]:
    """One athlete's camera track as the gateway publishes it (one observation per fix, tagged)."""
    return [Message("camera", {"athlete": athlete, "t_host_s": float(t), "position_m": [float(p[0]), float(p[1])],
                               "heading_rad": float(h)}) for t, p, h in zip(t_s, position_m, heading_rad)]


def in_stream_order(*streams: Iterable[Message]) -> list[Message]:
    """Several sources' messages interleaved by time, as they arrive at the console (stable for equal times)."""
    return sorted((m for s in streams for m in s), key=lambda m: m.header["t_host_s"])


def synthesize_athletes(setups: dict[str, SynthesisSetup], messages: Iterable[Message]) -> dict[str, list[FramePose]]:
    """Each athlete's poses from one mixed stream, routed by the console's bridge (samples to every synthesis,
    camera observations to their athlete's only); each synthesis is stepped after every message, as the live
    worker steps on arrival, then finished (end of take)."""
    bridge = GatewayBridge(TraceStore())
    sessions = {name: StreamSynthesis(lambda s=setup: s.engine.live(s.lag_s), setup.sensors, setup.engine.rate_hz,
                                      use_camera_heading=setup.use_camera_heading)
                for name, setup in setups.items()}
    for name, session in sessions.items():
        bridge.sample_sinks.append(session.add_samples)
        bridge.athlete_camera_sinks.setdefault(name, []).append(session.add_camera)
    poses: dict[str, list[FramePose]] = {name: [] for name in sessions}
    for msg in messages:
        (bridge.on_samples if msg.kind == "samples" else bridge.on_camera)(msg)
        for name, session in sessions.items():
            poses[name] += session.step()
    for name, session in sessions.items():
        poses[name] += session.finish()
    return poses
