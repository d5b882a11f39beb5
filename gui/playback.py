"""Playback of a gateway recording through the live pipeline.

A take (`gateway.recorder.load_take`) is turned back into the same messages the gateway streams and fed to the
same `gui.bridge.GatewayBridge`, so traces, camera pane, synthesis and skeleton view behave exactly as live
(QTM's "stream from file", x-IMU3's file connection). The console's tick calls `advance_to`; the scrubber calls
`seek`, which clears the trace history and replays the window before the new position."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from gateway.codec import Message
from gateway.recorder import load_take

from gui.bridge import GatewayBridge


class Playback:
    """Cursor over one recorded take, on the recording's gateway clock (seconds)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        take = load_take(self.path)
        self.problem = take.problem
        self.meta = take.meta
        self.samples = {k: v for k, v in take.samples.items() if "t_host_s" in v and "acc_g" in v and len(v["t_host_s"])}
        self.sample_athletes = {k: a for k, a in take.sample_athletes.items() if k in self.samples}
        self.others = sorted((m for m in take.others if "t_host_s" in m.header), key=lambda m: m.header["t_host_s"])
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
