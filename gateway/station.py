"""One reader thread per base-station link: bytes -> `StreamDecoder` -> clock-mapped sample blocks + statistics.

Lifecycle of a link (``link`` in status): ``connecting`` (opening, or open but no HELLO yet) -> ``streaming`` (data
within the last ``stale_after_s``) <-> ``stale`` (open, silent) -> ``lost`` (I/O error / unplugged; the reader
retries every ``reconnect_interval_s`` until the port reappears). On every (re)connect the reader sends
REQUEST_HELLO and START_STREAMING, so a station that was power-cycled or replugged resumes by itself.

Why frames before the first HELLO are held back (bounded): the tick rate needed to map times arrives in HELLO.
Why they are held back after every reconnect too, until that connection's HELLO: the port may now be another
station's (a ttyACM number or a pty reused by the next device plugged in); a HELLO with another serial than the
link's station closes the link and drops what it sent (`station_serial`), so one station's stream never takes in
another's samples.
Why the clock survives a replug with the same boot id: the station kept counting, so the fitted offset/skew stay
valid and the unwrapper bridges the gap from host elapsed time; a new boot id restarts the clock epoch.
"""
from __future__ import annotations

import logging
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol

import numpy as np

import firmware_protocol as fp
from gateway.clock import ClockEstimator, TickUnwrapper
from gateway.device_checks import batch_problem, hello_problem
from gateway.device_text import EventThrottle, escape as escape_device_text
from gateway.links import Link, LinkError, SerialLink
from gateway.reader_thread import ReaderThread
from gateway.stats import SensorStats

log = logging.getLogger(__name__)

PRE_HELLO_FRAMES = 5000
HELLO_RETRY_S = 1.0
CLOCK_PROBE_INTERVAL_S = 0.1
REFUSAL_EVENT_INTERVAL_S = 10.0  # at most one event per kind of refused message in this time (counts are exact)
ERROR_EVENT_BURST = 3  # station ERROR messages: this many events at once, then one per interval (all counted)
ERROR_EVENT_INTERVAL_S = 10.0


@dataclass
class SampleBlock:
    """One decoded batch of one sensor, mapped onto the gateway clock. Arrays share length N."""

    station: str
    sensor: int
    nominal_hz: float
    clock_locked: bool
    epoch: int  # clock epoch (increments on station reset)
    counter: np.ndarray  # (N,) uint32 per-sensor sample counter
    raw_ticks: np.ndarray  # (N,) uint32 device ticks as latched (wrapping)
    ticks: np.ndarray  # (N,) float64 unwrapped device ticks (period has 1/256-tick resolution)
    arrival_s: np.ndarray  # (N,) float64 host monotonic time the batch was read (same for the whole batch)
    t_host_s: np.ndarray  # (N,) float64 sample latch time on the gateway clock (online estimate)
    acc_g: np.ndarray  # (N, 3) float32
    # a sensor that streams them (protocol v2 MOTION_BATCH, x-IMU3 quaternions, Shimmer3 gyroscope); else None
    quat_wxyz: np.ndarray | None = None  # (N, 4) float32 unit quaternion sensor -> device earth (Z up), NaN = none
    gyro_rps: np.ndarray | None = None  # (N, 3) float32 angular rate, rad/s, sensor frame

    def header(self) -> dict[str, Any]:
        """The ``samples`` message header. With `arrays` this is the one definition of a samples message:
        clients receive it per batch, the recorder merges batches of it into chunks (docs/gateway.md)."""
        return {"station": self.station, "sensor": self.sensor, "nominal_hz": self.nominal_hz, "epoch": self.epoch,
                "clock_locked": self.clock_locked}

    def arrays(self) -> dict[str, np.ndarray]:
        """Every per-sample array (raw ticks + arrival times allow offline re-alignment); ``quat_wxyz`` and
        ``gyro_rps`` only when the sensor streams them (a sensor's batches all carry the same channels)."""
        arrays = {"counter": self.counter, "epoch": np.full(len(self.counter), self.epoch, np.uint32),
                  "raw_ticks": self.raw_ticks, "ticks": self.ticks,
                  "arrival_s": self.arrival_s, "t_host_s": self.t_host_s, "acc_g": self.acc_g}
        if self.quat_wxyz is not None:
            arrays["quat_wxyz"] = self.quat_wxyz
        if self.gyro_rps is not None:
            arrays["gyro_rps"] = self.gyro_rps
        return arrays


class StationSink(Protocol):
    """Where a reader delivers its output (the `Gateway`). Called on the reader thread: must not block.
    Optional: ``on_clock_point(station, epoch, raw_ticks, ticks, arrival_s, tick_hz)`` for every CLOCK_SYNC,
    so the recorder can keep the raw clock evidence for an offline re-fit; ``claim_station_name(reader, wanted)
    -> name`` once, at a link's first frame, so two links announcing one station id get different names."""

    def on_samples(self, block: SampleBlock) -> None: ...

    def on_station_event(self, station: str, level: str, message: str, details: dict | None = None) -> None: ...


@dataclass
class _Pending:
    event: threading.Event = field(default_factory=threading.Event)
    reply: fp.Ack | fp.Nack | None = None


class StationReader(ReaderThread):
    """Reads one link (serial path or URL, or any `Link` factory) on its own thread (`ReaderThread`)."""

    def __init__(
        self,
        source: str,
        sink: StationSink,
        *,
        open_link: Callable[[str], Link] = SerialLink,
        reconnect_interval_s: float = 0.2,
        stale_after_s: float = 0.5,
        clock_window_s: float = 60.0,
        lock_after_s: float = 30.0,
        clock_probe_interval_s: float = CLOCK_PROBE_INTERVAL_S,
    ):
        self.source = source
        self.sink = sink
        self._open_link = open_link
        self.reconnect_interval_s = reconnect_interval_s
        self.stale_after_s = stale_after_s
        self.clock_probe_interval_s = clock_probe_interval_s
        self._last_probe_s = -float("inf")
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._link: Link | None = None
        self._write_lock = threading.Lock()
        self._seq = 0
        self._command_ids = 0
        self._pending: dict[int, _Pending] = {}
        self.link_state = "connecting"
        self.transport = "hid" if source.startswith("hid:") else "serial"
        self.station_id: int | None = None
        self._claimed_name: str | None = None
        self.hello: fp.Hello | None = None
        self.reconnects = 0
        self.internal_errors = 0
        self.invalid_fields = 0  # HELLO / SAMPLE_BATCH messages refused for impossible field values
        self.last_invalid: str | None = None
        self._refusal_event_s: dict[str, float] = {}
        self.device_errors = 0  # ERROR messages from the station (events for them are throttled)
        self.last_device_error: str | None = None  # escaped
        self._error_throttle = EventThrottle(ERROR_EVENT_BURST, ERROR_EVENT_INTERVAL_S)
        self.link_error: str | None = None  # why the link cannot be opened (None once it is open)
        self._last_ticks: dict[object, float] = {}  # per sensor (last sample) and "sync": newest unwrapped ticks
        self.connected_at_s: float | None = None
        self.last_data_s: float | None = None
        self.decoder_totals: dict[str, int] = {}
        self._decoder = fp.StreamDecoder()
        self._pre_hello: deque[tuple[fp.DecodedFrame, float]] = deque(maxlen=PRE_HELLO_FRAMES)
        self._greeted = False  # this connection's HELLO has arrived (frames are held back until it has)
        self._foreign = False  # this connection's HELLO came from another station: everything it sends is dropped
        self.foreign_devices = 0  # HELLOs from another station (serial) on this link, refused
        self._hello_requested_s = 0.0
        self.unwrapper: TickUnwrapper | None = None
        self._epoch_at_hello = 0
        self.clock = ClockEstimator(window_s=clock_window_s, lock_after_s=lock_after_s)
        self.sensors: dict[int, SensorStats] = {}
        self.station_battery_pct: int | None = None
        self.station_buffered_samples: int | None = None

    # -- naming -----------------------------------------------------------------------------------------------
    @property
    def name(self) -> str:
        """Station id used everywhere downstream (``st<frame station id>``, or ``st<id>-dup<n>`` when another
        link already uses that id: `StationSink.claim_station_name`); the source until a frame arrives."""
        return self._claimed_name or self.source

    # -- thread (ReaderThread hooks) ---------------------------------------------------------------------------
    @property
    def thread_name(self) -> str:
        return f"gw-station-{self.source}"

    def _is_open(self) -> bool:
        return self._link is not None

    def _open(self) -> bool:
        return self.connect()

    def _close(self, reason: str) -> None:
        self._close_link(reason)

    def _serve(self) -> None:
        link = self._link
        if link is None:  # closed since the thread looked (a refused device, a failed greeting)
            return
        try:
            data = link.read(65536)
        except LinkError as exc:
            self._close_link(str(exc))
            return
        now = time.monotonic()
        if data:
            self.last_data_s = now
            try:
                self.feed(data, now)
            except Exception:  # a bug downstream must not stop acquisition of the next bytes
                self.internal_errors += 1
                log.exception("%s: processing failed", self.name)
        self._update_link_state(now)

    def connect(self) -> bool:
        """Open the link now and greet the station (the thread calls this; virtual-time harnesses call it
        directly with a link whose ``write`` goes to an emulator). False if the link cannot be opened."""
        try:
            link = self._open_link(self.source)
        except LinkError as exc:
            with self._lock:
                if self.link_state not in ("lost", "connecting"):
                    self.link_state = "lost"
                changed, self.link_error = str(exc) != self.link_error, str(exc)
            if changed:  # once per distinct reason, not every retry; the gateway logs events
                self.sink.on_station_event(self.name, "alarm", f"cannot open link: {exc}")
            return False
        with self._lock:
            self.link_error = None
            if self.connected_at_s is not None:
                self.reconnects += 1
            self._link = link
            self.transport = getattr(link, "transport", self.transport)
            self.connected_at_s = time.monotonic()
            self.link_state = "connecting"
            self._greeted = self._foreign = False
            self._pre_hello.clear()  # held back on a connection that never said which station it was
        self.sink.on_station_event(self.name, "info", f"link {self.source} open (reconnects: {self.reconnects})")
        self._send_commands_on_connect()
        return self._link is not None  # the device can vanish between the open and the greeting

    def _send_commands_on_connect(self) -> None:
        try:
            self._send_command(fp.Opcode.REQUEST_HELLO, expect_reply=False)
            self._send_command(fp.Opcode.START_STREAMING, expect_reply=False)
        except LinkError as exc:
            self._close_link(str(exc))

    def _close_link(self, reason: str) -> None:
        with self._lock:
            link, self._link = self._link, None
            if link is None:
                return
            self._accumulate_decoder_stats()
            self.link_state = "lost" if not self._stop.is_set() else "stopped"
        link.close()
        if not self._stop.is_set():  # the sink logs events (the gateway does), so no second log line here
            self.sink.on_station_event(self.name, "alarm", f"link lost: {reason}")

    def _accumulate_decoder_stats(self) -> None:
        """Keep counters of decoders from earlier connections (each connection starts a fresh decoder)."""
        for key, value in self._decoder_counts(self._decoder).items():
            self.decoder_totals[key] = self.decoder_totals.get(key, 0) + value
        self._decoder = fp.StreamDecoder()

    @staticmethod
    def _decoder_counts(decoder: fp.StreamDecoder) -> dict[str, int]:
        s = decoder.stats
        return {"bytes": s.bytes_received, "frames": s.frames_ok, "crc_errors": s.crc_errors,
                "framing_errors": s.cobs_errors + s.length_errors, "malformed": s.malformed_payloads,
                "frame_gaps": s.seq_gaps}

    def _update_link_state(self, now: float) -> None:
        with self._lock:
            if self._link is None:
                return
            if not self._greeted:  # stay "connecting"; re-ask in case the first request was lost
                if now - self._hello_requested_s > HELLO_RETRY_S:
                    self._hello_requested_s = now
                    try:
                        self._send_command(fp.Opcode.REQUEST_HELLO, expect_reply=False)
                    except LinkError as exc:
                        self._close_link(str(exc))
                return
            fresh = self.last_data_s is not None and now - self.last_data_s < self.stale_after_s
            new_state = "streaming" if fresh else "stale"
            if new_state != self.link_state:
                if new_state == "stale":
                    self.sink.on_station_event(self.name, "warning", "no data for "
                                               f"{now - (self.last_data_s or now):.1f} s")
                self.link_state = new_state

    # -- decoding ---------------------------------------------------------------------------------------------
    def feed(self, data: bytes, arrival_s: float) -> None:
        """Decode bytes that arrived at host time ``arrival_s``. The thread calls this for live links; replays and
        virtual-time benches call it directly (no thread, no link) to push recorded or emulated bytes through
        exactly the same path."""
        with self._lock:
            frames = self._decoder.feed(data)
            for frame in frames:
                self._handle(frame, arrival_s)
            if self.hello is not None and arrival_s - self._last_probe_s >= self.clock_probe_interval_s:
                self._probe_clock(arrival_s)

    def _probe_clock(self, now_s: float) -> None:
        """Ask for an extra CLOCK_SYNC. Why: beacons carry no radio latency (unlike sample batches), and the
        lower-envelope fit needs many of them; the periodic 1 Hz beacon alone leaves ~1 ms p99 error under
        20 ms USB jitter, 10 Hz probes bring it to ~0.1 ms. Fire-and-forget: a lost probe costs nothing."""
        self._last_probe_s = now_s
        try:
            self._send_command(fp.Opcode.REQUEST_CLOCK_SYNC, expect_reply=False)
        except LinkError:
            pass  # the read loop notices a dead link on its own

    def _handle(self, frame: fp.DecodedFrame, arrival_s: float) -> None:
        if self._foreign:
            return
        if self.station_id is None:
            # the sink may re-key a station whose id another link already uses (issue 22: two stations with one
            # id were merged into one stream that could not be separated afterwards)
            claim = getattr(self.sink, "claim_station_name", None)
            wanted = f"st{frame.station_id}"
            self._claimed_name = claim(self, wanted) if claim is not None else wanted
            self.station_id = frame.station_id
        elif frame.station_id != self.station_id and not self._greeted and self.hello is not None:
            self._refuse_foreign_device(f"station id {frame.station_id}", f"station id {self.station_id}")
            return
        elif frame.station_id != self.station_id:
            log.warning("%s: frame from station id %d on a link of station %d; ignored",
                        self.source, frame.station_id, self.station_id)
            return
        msg = frame.message
        if isinstance(msg, fp.Hello):
            problem = hello_problem(msg)
            if problem is not None:
                self._refuse("hello", problem)
                return
            if self.hello is not None and msg.station_serial != self.hello.station_serial:
                self._refuse_foreign_device(f"station serial {msg.station_serial:#x}",
                                            f"station serial {self.hello.station_serial:#x}")
                return
            self._greeted = True
            self._on_hello(msg)
            while self._pre_hello:
                self._handle(*self._pre_hello.popleft())
            return
        if not self._greeted:
            self._pre_hello.append((frame, arrival_s))
            return
        if isinstance(msg, fp.SampleBatch):
            self._on_batch(msg, arrival_s)
        elif isinstance(msg, fp.ClockSync):
            ticks = self._unwrap("sync", msg.station_ticks, arrival_s, "clock sync counter jumped")
            self._last_ticks["sync"] = ticks
            self.clock.add(ticks / self.hello.tick_rate_hz, arrival_s)
            on_clock_point = getattr(self.sink, "on_clock_point", None)
            if on_clock_point is not None:
                on_clock_point(self.name, self.unwrapper.epoch, msg.station_ticks, ticks, arrival_s,
                               self.hello.tick_rate_hz)
        elif isinstance(msg, fp.Status):
            self.station_battery_pct = msg.battery_pct
            self.station_buffered_samples = msg.buffered_samples
            for link in msg.links:
                stats = self._sensor(link.sensor_id)
                stats.rssi_dbm, stats.battery_pct = link.rssi_dbm, link.battery_pct
        elif isinstance(msg, (fp.Ack, fp.Nack)):
            pending = self._pending.pop(msg.command_id, None)
            if pending is not None:
                pending.reply = msg
                pending.event.set()
        elif isinstance(msg, fp.Error):
            self._on_device_error(msg)

    def _on_device_error(self, msg: fp.Error) -> None:
        """A station's ERROR: its text escaped (no forged log lines, no bidi tricks) and events throttled; every
        one is counted in status (``device_errors``, ``last_device_error``)."""
        self.device_errors += 1
        self.last_device_error = f"{msg.code}: {escape_device_text(str(msg.text))}"
        if self._error_throttle.allow(time.monotonic()):
            held = self._error_throttle.take_suppressed()
            self.sink.on_station_event(self.name, "warning", f"station error {self.last_device_error}"
                                       + (f" ({held} more station errors not shown)" if held else ""))

    def _sensor(self, sensor_id: int) -> SensorStats:
        stats = self.sensors.get(sensor_id)
        if stats is None:
            stats = self.sensors[sensor_id] = SensorStats(sensor_id)
        return stats

    def _on_hello(self, hello: fp.Hello) -> None:
        rebooted = self.hello is not None and (hello.boot_id, hello.tick_rate_hz) != (self.hello.boot_id,
                                                                                   self.hello.tick_rate_hz)
        if self.unwrapper is None:
            self.unwrapper = TickUnwrapper(hello.tick_rate_hz)
        elif rebooted and self.unwrapper.epoch == self._epoch_at_hello:
            # Frames of the new boot can precede its HELLO (the periodic beacon); if their ticks already started
            # a new epoch, this HELLO confirms that reboot instead of being a second one.
            self.unwrapper.restart(hello.tick_rate_hz)
            self._on_clock_reset(f"station rebooted (boot id {hello.boot_id:#x})")
        self._epoch_at_hello = self.unwrapper.epoch
        repeated = hello == self.hello  # the same boot's HELLO again (its unsolicited one, then our request's)
        self.hello = hello
        for info in hello.sensors:
            self._sensor(info.sensor_id).nominal_hz = float(info.rate_hz)
        if self.link_state == "connecting":
            self.link_state = "streaming"
        if repeated:  # nothing new to log or tell the consoles
            return
        self.sink.on_station_event(self.name, "info", "hello: firmware "
                                   f"{'.'.join(map(str, hello.firmware_version))}, {len(hello.sensors)} sensors, "
                                   f"{hello.tick_rate_hz} ticks/s", {"boot_id": hello.boot_id,
                                                                     "station_serial": hello.station_serial})

    def _refuse_foreign_device(self, found: str, own: str) -> None:
        """Another station answered on this link's port since the reconnect (`found`: its serial or id, `own`: this
        link's): drop what it sent and close the link; the reader keeps reopening the port until this link's own
        station is back there."""
        self.foreign_devices += 1
        self._foreign = True
        self._pre_hello.clear()
        self._close_link(f"{found} answered at {self.source}, where {own} was; its frames are dropped until that "
                         "station is back")

    def _refuse(self, kind: str, problem: str) -> None:
        """Drop a message whose fields are impossible: counted in status, one event per kind per interval."""
        self.invalid_fields += 1
        self.last_invalid = problem
        now = time.monotonic()
        if now - self._refusal_event_s.get(kind, -float("inf")) >= REFUSAL_EVENT_INTERVAL_S:
            self._refusal_event_s[kind] = now
            self.sink.on_station_event(self.name, "warning", f"refused {problem} ({self.invalid_fields} refused "
                                                             "so far; link kept)")

    def _unwrap(self, stream: object, raw_ticks: int, arrival_s: float, jump_reason: str) -> int:
        """Unwrap a tick value of one in-order stream (a sensor's batches, or the clock beacons). A far jump is a
        reset (TickUnwrapper); a step back within its tolerance is one too: a sensor's samples and the beacons
        are sent in tick order, so a value at or before the stream's last one means the device clock moved."""
        ticks, reset = self.unwrapper.unwrap(raw_ticks, arrival_s)
        if reset:
            self._on_clock_reset(jump_reason)
            return ticks
        last = self._last_ticks.get(stream)
        if last is not None and (ticks < last or (ticks == last and stream != "sync")):
            back_s = (last - ticks) / self.hello.tick_rate_hz
            self.unwrapper.restart()
            ticks, _ = self.unwrapper.unwrap(raw_ticks, arrival_s)
            where = "clock beacons" if stream == "sync" else f"sensor {stream}"
            self._on_clock_reset(f"device ticks went back by {back_s:.6f} s ({where})")
        return ticks

    def _on_clock_reset(self, why: str) -> None:
        self._last_ticks.clear()
        self.clock.restart()
        for stats in self.sensors.values():
            stats.restart_counter()
        self.sink.on_station_event(self.name, "warning", f"clock restarted: {why}")

    def _on_batch(self, batch: fp.SampleBatch, arrival_s: float) -> None:
        n = batch.n_samples
        if n == 0:
            return
        problem = batch_problem(batch, self.hello.tick_rate_hz)
        if problem is not None:
            self._refuse("batch", problem)
            return
        first = self._unwrap(batch.sensor_id, batch.first_sample_ticks, arrival_s,
                             "sample ticks jumped far from the prediction")
        offsets = np.arange(n) * batch.sample_period_ticks
        ticks = first + offsets
        self._last_ticks[batch.sensor_id] = float(ticks[-1])
        device_s = ticks / self.hello.tick_rate_hz
        self.clock.add(float(device_s[-1]), arrival_s)  # newest sample: least delivery latency
        stats = self._sensor(batch.sensor_id)
        stats.on_batch(batch.first_sample_counter, n, arrival_s)
        t_host = stats.monotonic_host_times(self.clock.to_host(device_s),  # never steps back (issue 22)
                                            batch.sample_period_ticks / self.hello.tick_rate_hz)
        self.sink.on_samples(SampleBlock(
            station=self.name, sensor=batch.sensor_id, nominal_hz=stats.nominal_hz,
            clock_locked=self.clock.state.locked, epoch=self.unwrapper.epoch,
            counter=np.arange(n, dtype=np.uint32) + np.uint32(batch.first_sample_counter),  # wraps like the wire
            raw_ticks=(batch.first_sample_ticks + np.round(offsets).astype(np.int64)).astype(np.uint32),
            ticks=ticks, arrival_s=np.full(n, arrival_s), t_host_s=t_host,
            acc_g=batch.samples.astype(np.float32) * np.float32(batch.scale_g_per_lsb),
            quat_wxyz=_float32_or_none(batch.quat_wxyz()), gyro_rps=_float32_or_none(batch.gyro_rps()),
        ))

    # -- commands ---------------------------------------------------------------------------------------------
    def _send_command(self, opcode: int, target: int = fp.BROADCAST_SENSOR, value: int = 0,
                      expect_reply: bool = True) -> _Pending:
        with self._write_lock:
            link = self._link
            if link is None:
                raise LinkError(f"{self.source}: not connected")
            self._command_ids = self._command_ids % 65535 + 1
            pending = _Pending()
            if expect_reply:
                self._pending[self._command_ids] = pending
            frame = fp.encode(fp.Command(self._command_ids, int(opcode), target, value),
                              self.station_id or 0, self._seq)
            self._seq += 1
            link.write(frame)
        return pending

    def command(self, opcode: int, target: int = fp.BROADCAST_SENSOR, value: int = 0, timeout_s: float = 1.0) -> dict:
        """Send a command and wait for its ACK/NACK. Returns ``{"acked": bool, "nack_reason": int|None}``."""
        pending = self._send_command(opcode, target, value)
        if not pending.event.wait(timeout_s):
            with self._write_lock:
                self._pending = {k: v for k, v in self._pending.items() if v is not pending}
            raise TimeoutError(f"{self.name}: no ACK/NACK for opcode {int(opcode)} within {timeout_s} s")
        reply = pending.reply
        return {"acked": isinstance(reply, fp.Ack), "nack_reason": getattr(reply, "reason", None)}

    # -- status -----------------------------------------------------------------------------------------------
    def status(self, now_s: float | None = None, rate_window_s: float = 1.0) -> dict:
        """Snapshot for the status message (docs/gateway.md "Station status")."""
        now_s = time.monotonic() if now_s is None else now_s
        with self._lock:
            counts = dict(self.decoder_totals)
            for key, value in self._decoder_counts(self._decoder).items():
                counts[key] = counts.get(key, 0) + value
            hello = self.hello
            kinds = {s.sensor_id: s.kind for s in hello.sensors} if hello else {}
            sensors = []
            for sensor_id in sorted(self.sensors):
                stats = self.sensors[sensor_id]
                stats.update_rate(now_s, rate_window_s)
                sensors.append({**stats.as_dict(), "channels": sensor_channels(kinds.get(sensor_id))})
            clock = self.clock.state.as_dict()
            if self.unwrapper is not None:
                clock["wraps"] = self.unwrapper.wraps
                clock["epoch"] = self.unwrapper.epoch
            return {
                "station": self.name, "source": self.source, "transport": self.transport, "link": self.link_state,
                "firmware": ".".join(map(str, hello.firmware_version)) if hello else None,
                "station_serial": hello.station_serial if hello else None,
                "boot_id": hello.boot_id if hello else None, "tick_hz": hello.tick_rate_hz if hello else None,
                "reconnects": self.reconnects, "internal_errors": self.internal_errors, "battery_pct": self.station_battery_pct,
                "invalid_fields": self.invalid_fields, "last_invalid": self.last_invalid, "link_error": self.link_error,
                "foreign_devices": self.foreign_devices,
                "device_errors": self.device_errors, "last_device_error": self.last_device_error,
                "device_error_events_suppressed": self._error_throttle.suppressed_total,
                "buffered_samples": self.station_buffered_samples, **counts,
                "clock": clock, "sensors": sensors,
            }


def sensor_channels(kind: int | None) -> list[str]:
    """The channels a HELLO sensor kind announces (`firmware_protocol.SensorKind` bits), in `EngineSpec.inputs`
    names: ``["acc"]``, ``["acc", "orientation", "gyro"]`` ...; a sensor not in the HELLO streams accelerations."""
    kind = fp.SensorKind.ACCELEROMETER if kind is None else kind
    bits = ((fp.SensorKind.ACCELEROMETER, "acc"), (fp.SensorKind.ORIENTATION, "orientation"),
            (fp.SensorKind.ANGULAR_RATE, "gyro"))
    return [name for bit, name in bits if kind & bit]


def _float32_or_none(values: np.ndarray | None) -> np.ndarray | None:
    return None if values is None else values.astype(np.float32)
