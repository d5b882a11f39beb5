"""The operator console window: wires the bridge, panes and worker threads together on one refresh tick.

Threads: the GatewayClient reader thread only fills `GatewayBridge`; the synthesis worker owns the engine;
control requests run on `RequestRunner`'s worker. The GUI thread runs a 60 Hz tick that drains, updates panes
and does at most one heavy redraw (traces or skeleton) — it never waits on the network or the engine."""
from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from PySide6 import QtCore, QtWidgets

from gui.athlete_status import athlete_status
from gui.bridge import GatewayBridge, SensorKey, gateway_clock_offset_s
from gui.control import RequestRunner
from gui.health import Alarm, Sync, status_alarms
from gui.playback import Playback
from gui.pose_pacing import PosePacer
from gui.render.placement import track_spot
from gui.ringbuffer import TraceStore
from gui.synthesis import SynthesisSetup
from gui.synthesis_process import Synthesizer, start_synthesis
from gui.widgets import VIEWER_ONLY
from gui.widgets.alarms import AlarmBar
from gui.widgets.athlete_status import AthleteStatusPanel
from gui.widgets.camera_pane import CameraPane
from gui.widgets.device_panel import DevicePanel
from gui.widgets.recording import PlaybackBar, RecordingPanel
from gui.widgets.skeleton_view import SkeletonView
from gui.widgets.traces import TracePanel

# Refresh timing (docs/console.md "Refresh timing"). The timer runs at 100 Hz so that a late tick costs a
# hundredth of a second, not a frame: with a 33 ms timer even a bare event loop tops out at 1000/33 = 30.3 ticks/s
# and every late tick drops the rate below 30; at 60 Hz, traces and skeleton at 30/s each needed every tick. Each
# tick does the cheap work (drain, panes) and at most ONE heavy redraw -- the traces (about TRACE_HZ) or the
# skeleton (when the pose pacer has the next pose) -- whichever waited longer, so no tick carries both and the
# event loop (paint, input, the gateway link) gets a turn between them.
REFRESH_HZ = 100.0
TICK_MS = int(1000 / REFRESH_HZ)
TRACE_HZ = 30.0
RECONNECT_INTERVAL_MS = 1000
SAVE_WAIT_S = 30.0  # save_poses: how long a synthesis step still in flight at close may take to finish
TruthProvider = Callable[[float], "np.ndarray | None"]  # gateway time (s) -> (J,3) m or None
# a take's events -> its ground truth (the demo stamps its takes; production takes have none)
TruthForTake = Callable[[list], "TruthProvider | None"]


HEALTH_RGB = {Sync.AMBER: (0.95, 0.75, 0.1), Sync.RED: (0.9, 0.12, 0.12)}


def segment_health_colours(sensor_joints: dict[SensorKey, int], health: dict[SensorKey, Sync]) -> dict[int, tuple]:
    """Joint -> colour for worn sensors that are amber or red (healthy segments keep the estimate's colour, so
    the figure only changes colour where the operator should look)."""
    return {joint: HEALTH_RGB[health[key]] for key, joint in sensor_joints.items()
            if health.get(key) in HEALTH_RGB}


class TickStats:
    """GUI-thread health over the last second: ticks/s, mean and max tick cost; per-stage totals for the bench."""

    def __init__(self) -> None:
        self.stage_s: dict[str, float] = {}  # cumulative GUI-thread seconds per tick stage (for the bench)
        self.stage_n: dict[str, int] = {}  # times each stage ran (the heavy redraws do not run every tick)
        self.t0 = time.perf_counter()
        self.ticks = 0
        self.busy_s = 0.0
        self.fps = 0.0
        self.tick_ms = 0.0
        self.max_tick_ms = 0.0
        self._max = 0.0

    def stage(self, name: str, t_start: float) -> float:
        """Add the time since ``t_start`` to stage ``name``; returns now (chain the next stage from it)."""
        now = time.perf_counter()
        self.stage_s[name] = self.stage_s.get(name, 0.0) + now - t_start
        self.stage_n[name] = self.stage_n.get(name, 0) + 1
        return now

    def record(self, cost_s: float) -> None:
        self.ticks += 1
        self.busy_s += cost_s
        self._max = max(self._max, cost_s)
        now = time.perf_counter()
        if now - self.t0 >= 1.0:
            self.fps = self.ticks / (now - self.t0)
            self.tick_ms = 1e3 * self.busy_s / max(1, self.ticks)
            self.max_tick_ms = 1e3 * self._max
            self.t0, self.ticks, self.busy_s, self._max = now, 0, 0.0, 0.0


class ConsoleWindow(QtWidgets.QMainWindow):
    def __init__(self, client: Any | None = None, *, synthesis: SynthesisSetup | None = None,
                 truth: TruthProvider | None = None, truth_parents: np.ndarray | None = None,
                 sensor_segments: dict[SensorKey, str] | None = None,
                 sensor_joints: dict[SensorKey, int] | None = None, truth_for_take: TruthForTake | None = None,
                 keep_poses: bool = False, make_client: Callable[[str, int], Any] | None = None,
                 title: str = "Courtside console", athlete: str | None = None,
                 more_athletes: dict[str, SynthesisSetup] | None = None) -> None:
        """``synthesis`` is the (first) athlete's, named ``athlete``; ``more_athletes`` the others' (issue 20):
        one synthesis worker each, fed by their own sensors and their own camera track."""
        super().__init__()
        self.setWindowTitle(title)
        self.client = client
        self.store = TraceStore(history_s=30.0)
        self.bridge = GatewayBridge(self.store)
        self.requests = RequestRunner(self)
        self.requests.done.connect(self._request_done)
        self.truth = truth
        self.truth_for_take = truth_for_take
        self.make_client = make_client  # (host, port) -> unconnected client with our credentials (reconnects)
        self.sensor_joints = sensor_joints or {}
        self.playback: Playback | None = None
        self.playing = False
        self.stats = TickStats()
        self._drawn_s = {"traces": 0.0, "skeleton": 0.0}  # perf_counter of each heavy redraw (_redraw_one)
        self._last_status_t: float | None = None
        self._groups_key: tuple = ()
        self._was_locked: set[str] = set()
        self._last_tap_t: float | None = None
        self._play_wall0 = 0.0
        self._play_t0 = 0.0
        self._make_panes(sensor_segments or {})
        self._lay_out()
        self._start_synthesis(synthesis, keep_poses, truth_parents, athlete, more_athletes)
        self._clock_offset_s = 0.0
        self._reconnecting = False
        self.reconnects = 0
        self._owns_client = False
        self._status_alarms: list[Alarm] = []
        if client is not None:
            self.bridge.attach(client)
            self._connected(client, gateway_clock_offset_s(client))
        self._start_timers()

    def _make_panes(self, sensor_segments: dict[SensorKey, str]) -> None:
        """The panes and controls, wired to this window's actions."""
        self.alarms = AlarmBar()
        self.athlete_status = AthleteStatusPanel()
        self.skeleton = SkeletonView()
        self.camera = CameraPane()
        self.traces = TracePanel(self.store)
        self.devices = DevicePanel()
        self.devices.set_mapping(sensor_segments)
        self.devices.sensor_athletes = self.bridge.sensor_athletes
        self.devices.identify_requested.connect(self._identify)
        self.recording = RecordingPanel()
        self.recording.required = sorted(sensor_segments)
        self.recording.start_requested.connect(self._start_recording)
        self.recording.stop_requested.connect(self._stop_recording)
        self.playbar = PlaybackBar()
        self.playbar.open_requested.connect(self._choose_take)
        self.playbar.play_toggled.connect(self._set_playing)
        self.playbar.seek_requested.connect(self.seek_playback)
        self.playbar.live_button.clicked.connect(self.back_to_live)
        self.lag_spin = QtWidgets.QDoubleSpinBox()
        self.lag_spin.setRange(0.1, 3.0)
        self.lag_spin.setSingleStep(0.1)
        self.lag_spin.setSuffix(" s lag")
        self.calibrate_button = QtWidgets.QPushButton("Calibrate…")
        self.calibrate_button.clicked.connect(self.open_calibration)
        self.wizard = None

    def _lay_out(self) -> None:
        """Skeleton and camera on top, the tabs below, the toolbar and alarms above, the status bar."""
        top = QtWidgets.QSplitter(QtCore.Qt.Horizontal)
        top.addWidget(self.skeleton)
        top.addWidget(self.camera)
        top.setSizes([640, 420])
        self.tabs = QtWidgets.QTabWidget()
        self.tabs.addTab(self.traces, "Traces")
        self.tabs.addTab(self.devices, "Devices")
        rec_tab = QtWidgets.QWidget()
        rec_layout = QtWidgets.QVBoxLayout(rec_tab)
        rec_layout.addWidget(self.recording)
        rec_layout.addWidget(self.playbar)
        rec_layout.addStretch(1)
        self.tabs.addTab(rec_tab, "Record / Playback")
        split = QtWidgets.QSplitter(QtCore.Qt.Vertical)
        split.addWidget(top)
        split.addWidget(self.tabs)
        split.setSizes([420, 380])
        toolbar = QtWidgets.QHBoxLayout()
        self.connection = QtWidgets.QLabel("not connected")
        for w in (self.connection, self.calibrate_button, QtWidgets.QLabel("Synthesis"), self.lag_spin):
            toolbar.addWidget(w)
        toolbar.addStretch(1)
        central = QtWidgets.QWidget()
        layout = QtWidgets.QVBoxLayout(central)
        layout.setContentsMargins(4, 4, 4, 4)
        layout.addLayout(toolbar)
        layout.addWidget(self.alarms)
        layout.addWidget(self.athlete_status)
        layout.addWidget(split, 1)
        self.setCentralWidget(central)
        self.status_label = QtWidgets.QLabel()
        self.statusBar().addWidget(self.status_label, 1)

    def _start_synthesis(self, synthesis: SynthesisSetup | None, keep_poses: bool, truth_parents: np.ndarray | None,
                         athlete: str | None, more_athletes: dict[str, SynthesisSetup] | None) -> None:
        """The synthesis worker of each athlete fed by the bridge (their lag on the toolbar), or the truth skeleton
        alone."""
        self.worker: Synthesizer | None = None
        self.synthesis = synthesis
        if synthesis is not None:
            self.skeleton.set_skeleton(synthesis.parents)
            self.worker = start_synthesis(synthesis, keep_poses=keep_poses)
            self.bridge.sample_sinks.append(self.worker.add_samples)
            if more_athletes and athlete is not None:  # only its own track: the other athlete's would drag it
                self.bridge.athlete_camera_sinks.setdefault(athlete, []).append(self.worker.add_camera)
            else:
                self.bridge.camera_sinks.append(self.worker.add_camera)
            self.bridge.recording_sinks.append(self.worker.recording_started)
            self.lag_spin.setValue(synthesis.lag_s)
            self.lag_spin.valueChanged.connect(self.worker.set_lag)
            self.lag_spin.setEnabled(synthesis.engine.lag_applies)
        else:
            self.lag_spin.setEnabled(False)
        self.athlete = athlete
        self.skeleton.athlete = athlete
        self.more_athletes = dict(more_athletes or {}) if synthesis is not None else {}
        self.other_workers: dict[str, Synthesizer] = {}
        for name, setup in self.more_athletes.items():
            other = start_synthesis(setup, keep_poses=keep_poses)
            self.bridge.sample_sinks.append(other.add_samples)
            self.bridge.athlete_camera_sinks.setdefault(name, []).append(other.add_camera)
            self.bridge.recording_sinks.append(other.recording_started)
            self.lag_spin.valueChanged.connect(other.set_lag)
            self.other_workers[name] = other
        # each athlete's poses paced for the 3-D view: "" the first athlete's (`worker`), then the others by name
        self._pacers: dict[str, PosePacer] = {}
        if self.worker is not None:
            self._pacers[""] = PosePacer(self.worker, synthesis.engine.rate_hz)
        for name, other in self.other_workers.items():
            self._pacers[name] = PosePacer(other, self.more_athletes[name].engine.rate_hz)
        if truth_parents is not None and synthesis is None:
            self.skeleton.set_skeleton(truth_parents)
        self.athlete_status.name_colours = self.skeleton.athlete_colours(list(self.workers()))

    def _start_timers(self) -> None:
        """The display tick and the link check (reconnects)."""
        self.timer = QtCore.QTimer(self)
        self.timer.setTimerType(QtCore.Qt.PreciseTimer)
        self.timer.timeout.connect(self.tick)
        self.timer.start(TICK_MS)
        self.link_timer = QtCore.QTimer(self)
        self.link_timer.timeout.connect(self.check_link)
        self.link_timer.start(RECONNECT_INTERVAL_MS)

    # -- gateway link -----------------------------------------------------------------------------------------
    def _connected(self, client: Any, clock_offset_s: float) -> None:
        self.client = client
        self._clock_offset_s = clock_offset_s
        hello = getattr(client, "server_hello", {}) or {}
        self.skeleton.sides = {str(a.get("name")): a.get("side") for a in hello.get("athletes") or []}
        viewer = getattr(client, "role", "operator") == "viewer"
        self.connection.setText(f"gateway {hello.get('gateway', '')} {client.host}:{client.port}"
                                + (" (viewer: watch only)" if viewer else ""))
        self.connection.setStyleSheet("")
        # the gateway checks the role of every request; a viewer console does not offer what it would refuse
        self.calibrate_button.setEnabled(not viewer)
        self.calibrate_button.setToolTip(VIEWER_ONLY if viewer else "")
        self.recording.set_allowed(not viewer)
        self.devices.set_commands_allowed(not viewer)

    def link_alarms(self) -> list[Alarm]:
        if self.client is None or self.playback is not None or self.client.connected:
            return []
        return [Alarm("gateway", "alarm", f"gateway {self.client.host}:{self.client.port} unreachable: reconnecting")]

    def synthesis_alarms(self) -> list[Alarm]:
        """A banner per athlete whose synthesis process crashed: a warning once restarted, an alarm when it was
        given up (the athlete's status says the same in red, `gui.athlete_status`)."""
        return [Alarm(f"synthesis:{name}", "warning", f"{name or 'synthesis'}: {worker.fault}") if worker.is_alive()
                else Alarm(f"synthesis-stopped:{name}", "alarm", f"{name or 'synthesis'}: {worker.fault}")
                for name, worker in self.workers().items() if worker.fault]

    def check_link(self) -> None:
        """Once a second: show a lost gateway connection or a crashed synthesis, and try to reconnect (off the GUI
        thread)."""
        self.alarms.set_conditions(self._status_alarms + self.link_alarms() + self.synthesis_alarms())
        if self.client is None or self.playback is not None or self.client.connected or self._reconnecting:
            return
        self.connection.setText(f"DISCONNECTED from {self.client.host}:{self.client.port}")
        self.connection.setStyleSheet("color: #e05050; font-weight: bold;")
        self._reconnecting = True
        self.requests.call("reconnect", self._reconnect, self.client.host, self.client.port)

    def _reconnect(self, host: str, port: int) -> tuple[Any, float]:
        """Worker thread: a fresh client, subscribed through the bridge, and its clock offset."""
        from gateway.client import GatewayClient

        client = (self.make_client or GatewayClient)(host, port).connect(timeout_s=1.0)
        try:
            self.bridge.detach()
            if self.worker is not None:
                # synthesis starts afresh on the new connection's data (queued before it, in-band): the frames
                # of the outage would otherwise all be pushed through the engine blind (12 s of them after a
                # gateway restart, as many as the outage was long)
                self._reset_workers()
            self.bridge.attach(client)
            return client, gateway_clock_offset_s(client)
        except Exception:
            client.close()
            raise

    def _reset_workers(self) -> None:
        """Every athlete's synthesis starts afresh (a reconnect, a playback seek, back to live)."""
        for worker in self.workers().values():
            worker.reset()
        for pacer in self._pacers.values():
            pacer.reset()

    # -- clock ----------------------------------------------------------------------------------------------
    def gateway_now_s(self) -> float:
        """Current time on the gateway clock (playback: the playback cursor)."""
        if self.playback is not None:
            return self.playback.cursor_s
        return time.monotonic() + self._clock_offset_s

    # -- the tick ---------------------------------------------------------------------------------------------
    def tick(self) -> None:
        t_start = t = time.perf_counter()
        if self.playback is not None and self.playing:
            self.playback.advance_to(self._play_t0 + (time.monotonic() - self._play_wall0), self.bridge)
            self.playbar.show_position(self.playback.cursor_s - self.playback.t_start_s)
            if self.playback.finished:
                self.playbar.play_button.setChecked(False)
        self.store.drain()
        t = self.stats.stage("drain", t)
        for ev in self.bridge.drain_events():
            self.alarms.add_event(str(ev.get("level", "info")), str(ev.get("source", "")), str(ev.get("message", "")))
        self._update_status()
        header, jpeg, trail = self.bridge.camera_frame()
        self.camera.update_camera(header, jpeg, trail, self.bridge.camera_rate)
        if self.bridge.athlete_cameras:
            self.camera.update_athletes(self.bridge.athlete_tracks(), self.bridge.camera_athlete)
        self.recording.show_state(self.bridge.latest("recording"), self.gateway_now_s())
        calibration = self.bridge.latest("calibration")
        self._mark_tap(calibration)
        if self.wizard is not None:
            self.wizard.show_state(calibration)
        self._update_groups()
        self._update_poses()
        t = self.stats.stage("panes", t)
        self._redraw_one(t)
        self.stats.record(time.perf_counter() - t_start)
        self._update_statusbar()

    def _redraw_one(self, t: float) -> None:
        """The tick's one heavy redraw: traces when due (TRACE_HZ, a tick early counts, so the traces keep 30/s
        on the 10 ms tick grid even when some ticks run late), the skeleton when a new pose waits; both due -> the
        one drawn longer ago."""
        traces_due = (self.tabs.currentWidget() is self.traces
                      and t - self._drawn_s["traces"] >= 1.0 / TRACE_HZ - 1.0 / REFRESH_HZ)
        skeleton_due = self.skeleton.pending()
        if traces_due and (not skeleton_due or self._drawn_s["traces"] <= self._drawn_s["skeleton"]):
            self.traces.refresh()
            self._drawn_s["traces"] = t
            self.stats.stage("traces", t)
        elif skeleton_due:
            self.skeleton.refresh()
            self._drawn_s["skeleton"] = t
            self.stats.stage("skeleton", t)

    def _update_status(self) -> None:
        status = self.bridge.latest("status")
        if not status or status.get("t_host_s") == self._last_status_t:
            return
        self._last_status_t = status.get("t_host_s")
        self.devices.update_status(status)
        self.skeleton.set_segment_colours(segment_health_colours(self.sensor_joints, self.devices.sensor_health))
        self.recording.status = status
        rec = self.bridge.latest("recording") or {}
        disk = str(Path(rec["path"]).parent) if rec.get("path") and Path(rec["path"]).parent.exists() else "."
        self._status_alarms = status_alarms(status, disk, self._was_locked)
        self.alarms.set_conditions(self._status_alarms + self.link_alarms() + self.synthesis_alarms())

    def _mark_tap(self, calibration: dict[str, Any] | None) -> None:
        """A sync tap found by the calibration workflow becomes an event marker on the traces."""
        tap = ((calibration or {}).get("state") or {}).get("tap")
        if tap and tap.get("t_s") != self._last_tap_t:
            self._last_tap_t = tap.get("t_s")
            self.store.put_event(float(tap["t_s"]), f"tap {tap.get('sensor_id', '')}")

    def _update_groups(self) -> None:
        groups = self.bridge.sensor_groups()
        key = tuple((g, tuple(v)) for g, v in groups.items())
        if key != self._groups_key:
            self._groups_key = key
            self.traces.set_groups(groups)

    def _update_poses(self) -> None:
        """Hand the 3-D view each athlete's next pose (gui.pose_pacing: every pose, at the synthesis rate), and
        nothing when no athlete has a new one: the same pose again would render the same frame again, taking a
        tick from the traces."""
        moved = [pacer.advance(time.monotonic()) for pacer in self._pacers.values()]
        pose = self._pacers[""].current if "" in self._pacers else None
        if pose is not None and not any(moved):
            return
        latest = {name: self._pacers[name].current for name in self.other_workers}
        estimate = pose.joint_positions_m if pose is not None else None
        self.skeleton.set_confidence(pose.confidence if pose is not None else None)
        t_pose = pose.t_s if pose is not None else self.store.latest_time()
        truth = self.truth(t_pose) if (self.truth is not None and t_pose is not None) else None
        self.skeleton.set_court_spots(self._court_spots(t_pose, latest))
        if estimate is not None or truth is not None:
            self.skeleton.set_poses(estimate, truth)
        if self.other_workers:
            self.skeleton.set_other_athletes({name: (None, None) if p is None else (p.joint_positions_m, p.confidence)
                                              for name, p in latest.items()})

    def _court_spots(self, t_first: float | None, others: dict[str, Any]) -> dict[str, np.ndarray | None]:
        """Each athlete's court (x, y) from its camera track at its pose's time (`gui.render.placement`); a console
        synthesizing one athlete takes the camera's first track (named or not)."""
        tracks = self.bridge.athlete_tracks()
        first = self.athlete or ""
        first_trail = tracks[first][1] if first in tracks else (
            None if self.other_workers else self.bridge.camera_frame()[2])
        spots = {first: None if first_trail is None else track_spot(first_trail, t_first)}
        for name, pose in others.items():
            spots[name] = track_spot(tracks[name][1], None if pose is None else pose.t_s) if name in tracks else None
        return spots

    def _update_statusbar(self) -> None:
        """The gateway's figures on the status bar; each athlete's synthesis in its own block (`athlete_status`)."""
        latest = self.store.latest_time()
        age = (self.gateway_now_s() - latest) * 1e3 if latest is not None else float("nan")
        parts = [f"gateway t {self.gateway_now_s():.2f} s", f"samples {self.bridge.samples_received}"
                 + (f" ({self.bridge.dropped_total} display frames dropped by the gateway)"
                    if self.bridge.dropped_total else ""),
                 f"newest sample age {age:.0f} ms",
                 f"GUI {self.stats.fps:.0f} fps, tick {self.stats.tick_ms:.1f} ms (max {self.stats.max_tick_ms:.0f})"]
        if self.playback is not None:
            parts.insert(0, f"PLAYBACK {self.playback.path.name}")
        self.status_label.setText("  |  ".join(parts))
        self.athlete_status.show_status([athlete_status(name, worker) for name, worker in self.workers().items()])

    def workers(self) -> dict[str, Synthesizer]:
        """Every athlete's synthesizer by name, the first athlete first ("" when the console names none)."""
        first = {self.athlete or "": self.worker} if self.worker is not None else {}
        return first | self.other_workers

    # -- control actions ----------------------------------------------------------------------------------------
    def _identify(self, station: str, sensor: int) -> None:
        if self.client is not None:
            self.requests.call("identify", self.client.station_command, station, "identify", sensor=sensor)

    def _start_recording(self, take: str) -> None:
        if self.client is not None:
            self.requests.call("start_recording", self.client.start_recording, take)

    def _stop_recording(self) -> None:
        if self.client is not None:
            self.requests.call("stop_recording", self.client.stop_recording)

    def _request_done(self, tag: str, result: Any, error: str) -> None:
        if tag == "reconnect":
            self._reconnecting = False
            if not error:
                self._connected(*result)
                self.reconnects += 1
                self._owns_client = True  # made by us: closed by `shutdown`
            return  # failures retry on the next link check; the banner already says so
        if error:
            self.alarms.add_event("warning", tag, error)
            if tag.endswith("recording"):
                self.recording.show_error(error)
        elif tag.endswith("recording") and isinstance(result, dict):
            self.bridge.set_latest("recording", result)
            self.bridge.note_recording(result)
        if tag.startswith("calibration") and self.wizard is not None:
            self.wizard.request_done(tag, result, error)

    def open_calibration(self) -> None:
        from gui.widgets.calibration_wizard import CalibrationWizard

        if self.wizard is None:
            self.wizard = CalibrationWizard(self._calibration_request, self.devices.mapping_names, parent=self)
        self.wizard.show()
        self.wizard.raise_()

    def _calibration_request(self, action: str, **args: Any) -> None:
        if self.client is not None:
            self.requests.call(f"calibration:{action}", self.client.calibration, action, **args)

    # -- playback -----------------------------------------------------------------------------------------------
    def _choose_take(self) -> None:
        path, _ = QtWidgets.QFileDialog.getOpenFileName(self, "Open take", "", "Courtside take (*.csrec)")
        if path:
            self.load_playback(path)

    def load_playback(self, take: str | Path | Playback) -> None:
        """Switch the views to a recorded take (live data stops being shown until `back_to_live`)."""
        if isinstance(take, Playback):
            playback = take
        else:
            try:
                playback = Playback(take)
            except (OSError, ValueError) as exc:  # unreadable file: tell the operator, keep the live view
                self.alarms.add_event("warning", "playback", str(exc))
                return
        path = playback.path
        if self.client is not None:
            self.bridge.detach()
        self.playback = playback
        if self.truth is None and self.truth_for_take is not None:
            self.truth = self.truth_for_take(playback.events)
            parents = getattr(self.truth, "parents", None)
            if parents is not None and self.skeleton.parents is None:
                self.skeleton.set_skeleton(parents)
        self.playbar.loaded(Path(path).parent.name if Path(path).name == "take.csrec" else Path(path).name,
                            playback.duration_s)
        self.seek_playback(0.0)

    def _set_playing(self, on: bool) -> None:
        if self.playback is None:
            return
        self.playing = on
        self._play_wall0, self._play_t0 = time.monotonic(), self.playback.cursor_s

    def seek_playback(self, t_rel_s: float) -> None:
        """Move the playback cursor to ``t_rel_s`` seconds into the take (the scrubber calls this)."""
        if self.playback is None:
            return
        if self.worker is not None:
            self._reset_workers()  # the stream jumps in time: start a fresh window
        self.playback.seek(self.playback.t_start_s + t_rel_s, self.bridge)
        self._play_wall0, self._play_t0 = time.monotonic(), self.playback.cursor_s
        self.playbar.show_position(self.playback.cursor_s - self.playback.t_start_s)

    def back_to_live(self) -> None:
        self.playback, self.playing = None, False
        self.playbar.play_button.setChecked(False)
        self.bridge.reset_history()
        if self.worker is not None:
            self._reset_workers()
        if self.client is not None and self.client.connected:
            self.bridge.attach(self.client)

    # -- saved poses -------------------------------------------------------------------------------------------
    def save_poses(self, path: str | Path) -> Path:
        """Write every pose kept since the engine's last (re)start (``keep_poses``), in the format
        `courtside synthesize --save-poses` writes (`engine.stream.poses_file`). With several athletes the first
        athlete's poses go to ``path`` and each other athlete's to ``<stem>.<athlete>.npz`` beside it; every file
        names its athlete in its metadata. Synthesis ends first (every worker stopped and waited for, up to
        `SAVE_WAIT_S`): a step still in flight when the window closed streams its poses out (BVH/VMC) before
        keeping them, and the file must hold every pose that went out."""
        from engine.errors import CourtsideError

        if self.worker is None or self.synthesis is None:
            raise CourtsideError(f"{path}: no synthesis ran in this console: no poses to save")
        for worker in self.workers().values():
            worker.stop()
            worker.join(timeout=SAVE_WAIT_S)
        path = Path(path)
        for name, worker in self.other_workers.items():
            self._save_worker_poses(path.with_name(f"{path.stem}.{name}{path.suffix or '.npz'}"), worker, name)
        return self._save_worker_poses(path, self.worker, self.athlete)

    def _save_worker_poses(self, path: Path, worker: Synthesizer, athlete: str | None) -> Path:
        from engine.stream.poses_file import save_poses

        start, poses = worker.poses()
        setup = worker.setup
        spec = setup.engine
        recording = self.bridge.latest("recording") or {}
        meta = {"engine": spec.name, "database": spec.database, "lag_s": worker.stats.lag_s,
                "rate_hz": spec.rate_hz, "start_frame": start, "take": recording.get("take"),
                "use_camera_heading": setup.use_camera_heading,
                "frames_in": worker.stats.frames_in, "frames_invalid": worker.stats.frames_invalid,
                "frames_with_camera": worker.stats.frames_with_camera,
                "engine_inputs": list(spec.inputs), "engine_label": spec.label,
                "frames_with_orientation": worker.stats.frames_with_orientation,
                "frames_with_gyro": worker.stats.frames_with_gyro,
                # live = offline needs the console to have seen every recorded sample: count what it missed
                "display_frames_dropped": self.bridge.dropped_total, "reconnects": self.reconnects,
                "late_samples": worker.stats.late_samples, "late_fixes": worker.stats.late_fixes,
                "sensors": [{"stream": f"{st}/{i}", "placement": name}
                            for (st, i), name in zip(setup.sensors, spec.sensor_names)]}
        if athlete is not None:
            meta["athlete"] = athlete
        return save_poses(path, poses, spec.parents, meta)

    # -- shutdown -----------------------------------------------------------------------------------------------
    def closeEvent(self, event: Any) -> None:
        self.shutdown()
        super().closeEvent(event)

    def shutdown(self) -> None:
        self.timer.stop()
        self.link_timer.stop()
        for worker in self.workers().values():
            worker.stop()
            worker.join(timeout=2)
        self.bridge.detach()
        self.requests.shutdown()
        if self._owns_client and self.client is not None:
            self.client.close()

