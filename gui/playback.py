"""Playback of a recording through the live pipeline.

A take (`gateway.recorder.load_take`) is turned back into the same messages the gateway streams and fed to the
same `gui.bridge.GatewayBridge`, so traces, camera pane, synthesis and skeleton view behave exactly as live
(QTM's "stream from file", x-IMU3's file connection). The console's tick calls `advance_to`; the scrubber calls
`seek`, which clears the trace history and replays the window before the new position.

An IMU file imported with `courtside import-imu` (a synthesis-input .npz) plays the same way, as one station
(``IMPORTED_STATION``) whose sensor k is the file's column k, named by its placement and its device's label
(`placements`, `source_labels`: the console maps the engine's sensors by the first, a `courtside calibrate`
record's ids by either). Its samples are the ones
`courtside synthesize` resamples (`engine.stream.frames.uniform_streams`, for the engine's frame rate: use
`for_frame_rate`), so the console shows the poses the file gets."""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from engine.errors import MalformedFileError
from engine.export_format import OPTIONAL_CHANNELS
from engine.graph.input_checks import check_take_file, open_npz
from engine.stream.frames import uniform_streams
from gateway.codec import Message
from gateway.recorder import load_take

from gui.bridge import GatewayBridge


IMPORTED_STATION = "imported"  # the one station an imported IMU file plays as
DEFAULT_FRAME_RATE_HZ = 30.0  # an imported file's samples before `for_frame_rate` (the shipped graphs' rate)


def is_imported_take(path: str | Path) -> bool:
    """Is ``path`` an .npz file (an `import-imu` take; the gateway's recordings are folders or .csrec files)."""
    return Path(path).suffix.lower() == ".npz" and Path(path).is_file()


class Playback:
    """Cursor over one recorded take, on the recording's gateway clock (seconds); an imported IMU file on its
    own clock (its first sample at 0 s)."""

    def __init__(self, path: str | Path, frame_rate_hz: float = DEFAULT_FRAME_RATE_HZ) -> None:
        self.path = Path(path)
        self.frame_rate_hz = float(frame_rate_hz)
        self.placements: dict[tuple[str, int], str] = {}  # sensor -> placement name, where the file names it
        self.source_labels: dict[tuple[str, int], str] = {}  # sensor -> the device's own name for it, likewise
        if is_imported_take(self.path):
            self._load_imported()
        else:
            self._load_recording()
        self._span_and_cursor()

    def _load_recording(self) -> None:
        take = load_take(self.path)
        self.problem = take.problem
        self.meta = take.meta
        self.samples = {k: v for k, v in take.samples.items() if "t_host_s" in v and "acc_g" in v and len(v["t_host_s"])}
        self.sample_athletes = {k: a for k, a in take.sample_athletes.items() if k in self.samples}
        self.others = sorted((m for m in take.others if "t_host_s" in m.header), key=lambda m: m.header["t_host_s"])

    def _load_imported(self) -> None:
        """The file's columns as `uniform_streams` gives them (MalformedFileError naming the file otherwise)."""
        with open_npz(self.path) as data:
            if "acc_g" not in data.files:
                raise MalformedFileError(self.path, None, "not an import-imu take (no 'acc_g'); a gateway "
                                                          "recording plays from its take folder or take.csrec")
            check_take_file(self.path, data)
            if "position_m" in data.files or "heading_rad" in data.files:
                raise MalformedFileError(self.path, None, "holds a camera track, which the console's playback of "
                                                          "an IMU file does not replay (synthesize it instead)")
            acc = np.asarray(data["acc_g"], float)
            names = [str(n) for n in data["sensor_names"]] if "sensor_names" in data.files else \
                [f"sensor{k}" for k in range(acc.shape[1])]
            labels = [str(n) for n in data["source_labels"]] if "source_labels" in data.files else names
            channels = {name: np.asarray(data[name], float) for name in OPTIONAL_CHANNELS if name in data.files}
            self._imported = (acc, float(data["fps"]), channels)
        self.problem, self.meta, self.sample_athletes, self.others = None, {}, {}, []
        for k in range(acc.shape[1]):
            self.placements[(IMPORTED_STATION, k)] = names[k]
            self.source_labels[(IMPORTED_STATION, k)] = labels[k]
        self._resample_imported()

    def _resample_imported(self) -> None:
        """The imported file's samples at `frame_rate_hz`, as `courtside synthesize` resamples them."""
        acc, fps, channels = self._imported
        self.samples = {}
        for k, (t, acc_k, quat, gyro) in enumerate(uniform_streams(acc, fps, self.frame_rate_hz, **channels)):
            arrays = {"t_host_s": t, "acc_g": acc_k}
            for name, values in (("quat_wxyz", quat), ("gyro_rps", gyro)):
                if values is not None:
                    arrays[name] = values
            self.samples[(IMPORTED_STATION, k)] = arrays

    def for_frame_rate(self, frame_rate_hz: float) -> "Playback":
        """This take for an engine at ``frame_rate_hz``: an imported file's samples are held half a frame beyond
        its ends (`uniform_streams`), so they depend on it (resampled from the arrays read once); a recording's
        do not."""
        if not is_imported_take(self.path) or float(frame_rate_hz) == self.frame_rate_hz:
            return self
        other = copy.copy(self)
        other.frame_rate_hz = float(frame_rate_hz)
        other._resample_imported()
        other._span_and_cursor()
        return other

    def _span_and_cursor(self) -> None:
        """The take's time span, its events, and the cursor before its first sample."""
        self._other_t = np.array([m.header["t_host_s"] for m in self.others], float)
        starts = [v["t_host_s"][0] for v in self.samples.values()] + list(self._other_t[:1])
        ends = [v["t_host_s"][-1] for v in self.samples.values()] + list(self._other_t[-1:])
        if not starts:
            raise ValueError(f"{self.path}: recording holds no timed samples or messages")
        self.t_start_s, self.t_end_s = float(min(starts)), float(max(ends))
        self.events = [dict(m.header) for m in self.others if m.kind == "event"]
        self.cursor_s = self.t_start_s - 1e-9  # so the very first sample is delivered

    def athlete_stations(self) -> dict[str, str]:
        """Athlete -> the station of its first sensor, for every athlete the recording names (in station order):
        what the live console reads from the gateway's hello (`gui.athletes_replay.athlete_stations`)."""
        out: dict[str, str] = {}
        for (station, _), athlete in sorted(self.sample_athletes.items()):
            out.setdefault(athlete, station)
        return out

    @property
    def duration_s(self) -> float:
        return self.t_end_s - self.t_start_s

    def _feed(self, bridge: GatewayBridge, t_from: float, t_to: float) -> int:
        """Deliver every sample/message with t_from < t <= t_to to the bridge; returns samples delivered.

        The slice's camera fixes and events go first: a synthesis that saw the slice's samples before the take's
        first fix would push its first frames as if there were no camera (a race with the worker thread), so the
        poses of a take would depend on the timing of the replay, not only on the recording."""
        j0, j1 = np.searchsorted(self._other_t, [t_from, t_to], side="right")
        for msg in self.others[j0:j1]:
            if msg.kind == "camera":
                bridge.on_camera(msg)
            elif msg.kind == "event":
                bridge.on_event(msg)
        n = 0
        for (station, sensor), arrays in self.samples.items():
            t = arrays["t_host_s"]
            i0, i1 = np.searchsorted(t, [t_from, t_to], side="right")
            if i1 > i0:
                header = {"station": station, "sensor": sensor, "nominal_hz": 0.0, "clock_locked": True}
                if (station, sensor) in self.sample_athletes:  # as live: traces and panels group per athlete
                    header["athlete"] = self.sample_athletes[(station, sensor)]
                bridge.on_samples(Message("samples", header, {k: v[i0:i1] for k, v in arrays.items()}))
                n += int(i1 - i0)
        return n

    def advance_to(self, t_s: float, bridge: GatewayBridge) -> int:
        """Play forward to ``t_s`` (clamped to the take)."""
        t_s = float(np.clip(t_s, self.t_start_s, self.t_end_s))
        n = self._feed(bridge, self.cursor_s, t_s) if t_s > self.cursor_s else 0
        self.cursor_s = t_s
        return n

    def seek(self, t_s: float, bridge: GatewayBridge, history_s: float = 10.0) -> None:
        """Jump to ``t_s``: forget shown history and replay the ``history_s`` before it."""
        bridge.reset_history()
        t_s = float(np.clip(t_s, self.t_start_s, self.t_end_s))
        self.cursor_s = max(self.t_start_s - 1e-9, t_s - history_s)
        self.advance_to(t_s, bridge)

    @property
    def finished(self) -> bool:
        return self.cursor_s >= self.t_end_s
