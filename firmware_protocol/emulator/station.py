"""The emulated base-station firmware: a deterministic state machine over virtual time.

`write(bytes)` takes host->station bytes (COMMAND frames) and answers at the current virtual time;
`advance(seconds)` runs the station forward and returns exactly the bytes it put on the USB wire in that span.
Transports (pty, emu:// URL, fake HID) and real-time pacing are layers on top.

Determinism: every random draw comes from a per-purpose generator consumed in a fixed order (per sensor, per
batch, per wire byte), and events are ordered by (time, kind, sensor, counter), so the output depends only on
the configuration, the seed and the times at which commands arrive -- not on how `advance` is chunked.

Model (see PROTOCOL.md section 4 and docs/protocol.md):
- The station is the clock master: sensor s samples on the station crystal grid, staggered by s/S of a period
  (TDMA slots), and collects `batch_samples` samples per radio batch.
- A batch is lost on the radio with probability `radio_loss`; otherwise it reaches the station after
  `latency_s` + an exponential jitter (mean `jitter_s`), and with probability `burst_probability` only after
  a radio outage of `burst_duration_s`. Batches of one sensor arrive in order (a blocked radio queues them),
  which is what makes deliveries bursty.
- Every byte on the USB wire is damaged (XOR with a random non-zero byte) with probability `byte_corruption`.
- The station is bus powered: `unplug()` loses everything in flight; `replug()` is a fresh boot (new boot id,
  seq/ticks/counters restart at 0, streaming off) that keeps rate and range (flash).
"""
from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field

import numpy as np

from ..codec import MAX_MOTION_BATCH_SAMPLES, message_type_and_payload
from ..decoder import StreamDecoder
from ..framing import frame_payload
from ..messages import (
    BROADCAST_SENSOR,
    INT16_FULL_SCALE,
    PERIODIC_BEACON,
    QUAT_Q14_ONE,
    Ack,
    BatchFlags,
    ClockSync,
    Command,
    Error,
    ErrorCode,
    Hello,
    Message,
    Nack,
    NackReason,
    Opcode,
    SampleBatch,
    SensorInfo,
    SensorKind,
    SensorLink,
    StationFlags,
    Status,
    scale_for_range,
)
from .clock import CrystalClock
from .ground_truth import BatchRecord, Fate, FrameRecord, GroundTruthLog
from .motion import MotionSource, OrientationSource, StillSource

SEQ_MODULUS = 1 << 32

# event kinds double as tie-break priority at equal times
_BEACON, _STATUS, _DROP, _BATCH = 0, 1, 2, 3
_OPCODES = frozenset(int(o) for o in Opcode)


@dataclass(frozen=True)
class StationConfig:
    station_id: int = 1
    serial: int = 0xC0DE0001
    firmware_version: tuple[int, int, int] = (1, 0, 0)
    n_sensors: int = 6
    rate_hz: int = 100
    range_g: int = 12
    supported_rates_hz: tuple[int, ...] = (25, 50, 100, 200, 500, 1000)
    supported_ranges_g: tuple[int, ...] = (2, 4, 8, 12, 16)
    tick_rate_hz: int = 1_000_000
    tick_offset: int = 0                 # u32 tick register at the first boot (replugs restart at 0)
    drift_ppm: float = 0.0               # crystal error vs true time; + = station clock runs fast
    batch_samples: int = 5               # samples per radio batch
    noise_g: float = 0.0                 # white sensor noise, g RMS (ground truth keeps the noise-free value)
    radio_loss: float = 0.0              # probability a batch is lost on the radio
    latency_s: float = 0.002             # radio latency floor
    jitter_s: float = 0.002              # mean of the exponential extra latency
    burst_probability: float = 0.0       # probability a batch hits a radio outage
    burst_duration_s: float = 0.2
    byte_corruption: float = 0.0         # per-byte probability on the USB wire
    beacon_interval_s: float = 1.0       # CLOCK_SYNC period, station-clock seconds
    status_interval_s: float = 1.0       # STATUS period, station-clock seconds
    autostart: bool = False              # stream from boot without START_STREAMING (demo convenience)
    orientation: bool = False            # sensors also stream orientation + angular rate (MOTION_BATCH, v2)
    gyro_range_dps: int = 2000           # full-scale angular rate, +-deg/s (i16 counts)
    seed: int = 0

    def __post_init__(self) -> None:
        problems = []
        if not 1 <= self.n_sensors <= 254:
            problems.append(f"n_sensors {self.n_sensors} not in 1..254")
        if self.rate_hz not in self.supported_rates_hz:
            problems.append(f"rate {self.rate_hz} Hz not in {self.supported_rates_hz}")
        if self.range_g not in self.supported_ranges_g:
            problems.append(f"range {self.range_g} g not in {self.supported_ranges_g}")
        if not 1 <= self.batch_samples <= 600:
            problems.append(f"batch_samples {self.batch_samples} not in 1..600")
        if self.orientation and self.batch_samples > MAX_MOTION_BATCH_SAMPLES:
            problems.append(f"batch_samples {self.batch_samples} > {MAX_MOTION_BATCH_SAMPLES} (with orientation)")
        if self.gyro_range_dps <= 0:
            problems.append("gyro_range_dps must be > 0")
        for name in ("radio_loss", "burst_probability", "byte_corruption"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                problems.append(f"{name} {getattr(self, name)} not a probability")
        for name in ("latency_s", "jitter_s", "burst_duration_s", "noise_g"):
            if getattr(self, name) < 0:
                problems.append(f"{name} must be >= 0")
        if self.beacon_interval_s <= 0 or self.status_interval_s <= 0:
            problems.append("beacon/status intervals must be > 0")
        if not 0 <= self.station_id <= 0xFFFF:
            problems.append(f"station_id {self.station_id} not a u16")
        if problems:
            raise ValueError("invalid station config: " + "; ".join(problems))


@dataclass
class _Sensor:
    sensor_id: int
    index: int                           # column in the motion source
    rate_hz: int
    range_g: int
    radio_rng: np.random.Generator = field(repr=False)
    noise_rng: np.random.Generator = field(repr=False)
    next_counter: int = 0                # counter of the next sample to be taken
    grid_start_ticks: float = 0.0        # since-boot ticks of run sample 0
    next_j: int = 0                      # run index of the next sample not yet in a batch
    radio_free_s: float = 0.0            # the radio delivers in order: next arrival no earlier than this


class BaseStation:
    """One emulated base station with `config.n_sensors` wireless accelerometers. Not thread-safe: the
    transports serialise access."""

    def __init__(self, config: StationConfig = StationConfig(), motion: MotionSource | None = None) -> None:
        self.config = config
        self.motion = motion if motion is not None else StillSource(config.n_sensors)
        if self.motion.n_sensors < config.n_sensors:
            raise ValueError(f"motion source has {self.motion.n_sensors} sensors, station needs {config.n_sensors}")
        if config.orientation and not (isinstance(self.motion, OrientationSource)
                                       and getattr(self.motion, "streams_orientation", True)):
            raise ValueError(f"{type(self.motion).__name__} gives no orientation; the station streams orientation")
        self.now_s = 0.0
        self.plugged = True
        self.truth = GroundTruthLog()
        self.bytes_out = 0                       # bytes ever returned by advance()
        self._boot_index = -1
        self._misc_rng = np.random.default_rng([config.seed, 1])
        self._wire_hit_rng = np.random.default_rng([config.seed, 2])     # which bytes (one draw per byte)
        self._wire_xor_rng = np.random.default_rng([config.seed, 3])     # how they change (one per hit)
        self._sensors = [
            _Sensor(i, i, config.rate_hz, config.range_g,
                    np.random.default_rng([config.seed, 100, i]), np.random.default_rng([config.seed, 200, i]))
            for i in range(config.n_sensors)
        ]
        self._last_wire_byte_damaged = False
        self._boot()

    # ------------------------------------------------------------------ lifecycle
    def _boot(self) -> None:
        cfg = self.config
        self._boot_index += 1
        self.boot_time_s = self.now_s
        self.clock = CrystalClock(cfg.tick_rate_hz, cfg.tick_offset if self._boot_index == 0 else 0, cfg.drift_ppm)
        self.boot_id = int(self._misc_rng.integers(1, 2**32))
        self._seq = 0
        self._streaming = False
        self._calibrating = False
        self._identify_until_s = -math.inf
        self._beacon_counter = 0
        self._next_beacon = 1
        self._next_status = 1
        self._radio_drops = 0
        self._host_frames_rejected = 0
        self._events: list[tuple] = []
        self._host_decoder = StreamDecoder()
        self._out = bytearray(b"\x00")           # a leading delimiter flushes whatever the host had buffered
        self._out_frames: list[FrameRecord] = []
        self._event_time_s = self.now_s
        for s in self._sensors:
            s.next_counter = 0
            s.next_j = 0
            s.radio_free_s = self.now_s
        self._send(self._hello())
        if cfg.autostart:
            self._start_streaming()

    def unplug(self, bytes_delivered: int | None = None) -> None:
        """Pull the cable now. `bytes_delivered`: how many of the `bytes_out` bytes the transport really handed
        to the host; frames past that point are marked lost (they sat in a transport queue)."""
        if not self.plugged:
            return
        if self._streaming:
            for s in self._sensors:             # samples already taken but not yet batched die with the link
                self._generate(s, self.now_s)
                rec = self._take_partial(s, self.now_s)
                if rec is not None:
                    rec.fate = Fate.LOST_UNPLUGGED
        for *_, payload in self._events:
            if isinstance(payload, BatchRecord) and payload.fate == Fate.IN_FLIGHT:
                payload.fate = Fate.LOST_UNPLUGGED
        unsent_end = self.bytes_out + len(self._out)
        self.lose_output(self.bytes_out if bytes_delivered is None else bytes_delivered, unsent_end)
        self._events.clear()
        self._out.clear()
        self._out_frames.clear()
        self.plugged = False

    def lose_output(self, start: int, end: int) -> None:
        """The transport dropped output bytes [start, end) (stream offsets): mark the frames they touched lost."""
        for frame in reversed(self.truth.frame_log):
            if frame.byte_offset + frame.n_bytes <= start:
                break
            if frame.byte_offset < end:
                frame.intact = False
                if frame.batch is not None:
                    frame.batch.fate = Fate.LOST_UNPLUGGED

    def replug(self) -> None:
        """Power comes back: a fresh boot at the current time."""
        if not self.plugged:
            self.plugged = True
            self._last_wire_byte_damaged = False
            self._boot()

    # ------------------------------------------------------------------ host side
    def write(self, data: bytes) -> None:
        """Bytes from the host (COMMAND frames). Replies are queued and returned by the next `advance`."""
        if not self.plugged:
            return
        stats = self._host_decoder.stats
        before = (stats.corrupt_frames, stats.malformed_payloads, stats.unsupported_version)
        frames = self._host_decoder.feed(data)
        self._event_time_s = self.now_s
        bad, malformed, version = (a - b for a, b in zip(
            (stats.corrupt_frames, stats.malformed_payloads, stats.unsupported_version), before))
        self._host_frames_rejected += bad + malformed + version
        for _ in range(bad):
            self._send(Error(ErrorCode.BAD_FRAME, "host frame failed COBS/length/CRC check"))
        for _ in range(version):
            self._send(Error(ErrorCode.UNSUPPORTED_VERSION, "protocol version not supported"))
        for _ in range(malformed):
            self._send(Nack(0, 0, NackReason.MALFORMED))
        for frame in frames:
            if isinstance(frame.message, Command):
                self._handle(frame.message)
            else:
                self._send(Error(ErrorCode.UNEXPECTED_MESSAGE, f"{type(frame.message).__name__} is station-only"))

    def _handle(self, cmd: Command) -> None:
        op = cmd.opcode
        reason = self._check(cmd)
        if reason is not None:
            self._send(Nack(cmd.command_id, op, reason))
            return
        self._send(Ack(cmd.command_id, op))
        targets = self._targets(cmd.target)
        if op == Opcode.START_STREAMING:
            self._start_streaming()
        elif op == Opcode.STOP_STREAMING:
            self._stop_streaming()
        elif op == Opcode.SET_RATE:
            for s in targets:
                s.rate_hz = cmd.value
        elif op == Opcode.SET_RANGE:
            for s in targets:
                s.range_g = cmd.value
        elif op == Opcode.IDENTIFY:
            self._identify_until_s = self.now_s + cmd.value / 1000.0
        elif op == Opcode.ENTER_CALIBRATION:
            self._calibrating = True
        elif op == Opcode.LEAVE_CALIBRATION:
            self._calibrating = False
        elif op == Opcode.REQUEST_HELLO:
            self._send(self._hello())
        elif op == Opcode.REQUEST_STATUS:
            self._send(self._status())
        elif op == Opcode.REQUEST_CLOCK_SYNC:
            self._send_beacon(cmd.command_id)

    def _check(self, cmd: Command) -> NackReason | None:
        op, cfg = cmd.opcode, self.config
        if op not in _OPCODES:
            return NackReason.UNKNOWN_OPCODE
        if op in (Opcode.SET_RATE, Opcode.SET_RANGE, Opcode.IDENTIFY) and not self._targets(cmd.target):
            return NackReason.UNKNOWN_SENSOR
        if op in (Opcode.SET_RATE, Opcode.SET_RANGE) and self._streaming:
            return NackReason.INVALID_STATE
        if op == Opcode.SET_RATE and cmd.value not in cfg.supported_rates_hz:
            return NackReason.UNSUPPORTED_VALUE
        if op == Opcode.SET_RANGE and cmd.value not in cfg.supported_ranges_g:
            return NackReason.UNSUPPORTED_VALUE
        if op == Opcode.IDENTIFY and cmd.value < 0:
            return NackReason.UNSUPPORTED_VALUE
        return None

    def _targets(self, target: int) -> list[_Sensor]:
        if target == BROADCAST_SENSOR:
            return self._sensors
        return [s for s in self._sensors if s.sensor_id == target]

    # ------------------------------------------------------------------ time
    def advance(self, seconds: float) -> bytes:
        """Run `seconds` of emulated time; return every byte put on the USB wire (command replies included)."""
        if seconds < 0:
            raise ValueError(f"cannot advance by {seconds} s")
        t_end = self.now_s + seconds
        if not self.plugged:
            self.now_s = t_end
            return b""
        if self._streaming:
            for s in self._sensors:
                self._generate(s, t_end)
        self._schedule_periodic(t_end)
        while self._events and self._events[0][0] <= t_end:
            t, kind, _, _, payload = heapq.heappop(self._events)
            self._event_time_s = t
            if kind == _BEACON:
                self._send_beacon(PERIODIC_BEACON)
            elif kind == _STATUS:
                self._send(self._status())
            elif kind == _DROP:
                self._radio_drops += 1
            else:
                self._send_batch(payload)
        self.now_s = t_end
        self._event_time_s = t_end
        return self._flush_wire()

    def _seconds_since_boot_to_true(self, device_seconds: float) -> float:
        """True time at which the station's own clock shows `device_seconds` since boot."""
        return self.boot_time_s + device_seconds * self.clock.tick_rate_hz / self.clock.true_rate_hz

    def _schedule_periodic(self, t_end: float) -> None:
        cfg = self.config
        for attr, interval, kind in (("_next_beacon", cfg.beacon_interval_s, _BEACON),
                                     ("_next_status", cfg.status_interval_s, _STATUS)):
            while (t := self._seconds_since_boot_to_true(getattr(self, attr) * interval)) <= t_end:
                heapq.heappush(self._events, (t, kind, 0, getattr(self, attr), None))
                setattr(self, attr, getattr(self, attr) + 1)

    # ------------------------------------------------------------------ sampling
    def _start_streaming(self) -> None:
        if self._streaming:
            return
        now_ticks = float(self.clock.ticks_since_boot(self.now_s - self.boot_time_s))
        n = len(self._sensors)
        for s in self._sensors:
            period = self.config.tick_rate_hz / s.rate_hz
            s.grid_start_ticks = math.ceil(now_ticks / period) * period + s.index * period / n
            s.next_j = 0
        self._streaming = True

    def _stop_streaming(self) -> None:
        if not self._streaming:
            return
        for s in self._sensors:
            self._generate(s, self.now_s)
            rec = self._take_partial(s, self.now_s)
            if rec is not None:
                self._radio(s, [rec])
        self._streaming = False

    def _last_index(self, s: _Sensor, t: float) -> int:
        """Run index of the last sample sensor s has taken by true time t (-1 if none)."""
        period = self.config.tick_rate_hz / s.rate_hz
        ticks = float(self.clock.ticks_since_boot(t - self.boot_time_s))
        return math.floor((ticks - s.grid_start_ticks) / period)

    def _generate(self, s: _Sensor, t_end: float) -> None:
        """Take every complete batch sensor s finishes by t_end and put it on the radio."""
        k = self.config.batch_samples
        n_batches = (self._last_index(s, t_end) - s.next_j + 1) // k
        if n_batches > 0:
            self._radio(s, self._take(s, n_batches * k, k))

    def _take_partial(self, s: _Sensor, t: float) -> BatchRecord | None:
        n = self._last_index(s, t) - s.next_j + 1
        return self._take(s, n, n)[0] if n > 0 else None

    def _take(self, s: _Sensor, n: int, per_batch: int) -> list[BatchRecord]:
        """Sample n times (next run indices), split into records of `per_batch` samples."""
        period = self.config.tick_rate_hz / s.rate_hz
        ticks_since_boot = s.grid_start_ticks + (s.next_j + np.arange(n)) * period
        t_true = self.boot_time_s + self.clock.seconds_since_boot(ticks_since_boot)
        acc = self.motion.acceleration_g(t_true)[:, s.index, :]
        measured = acc + s.noise_rng.normal(0.0, self.config.noise_g, acc.shape) if self.config.noise_g else acc
        scale = scale_for_range(s.range_g)
        counts = np.clip(np.rint(measured / scale), -INT16_FULL_SCALE, INT16_FULL_SCALE).astype(np.int16)
        latched = self.clock.counter(ticks_since_boot)
        flags = int(BatchFlags.CALIBRATING) if self._calibrating else 0
        quat = gyro = quat_q14 = gyro_counts = None
        if self.config.orientation:  # the motion source's readings already carry the filter's error model
            quat = self.motion.orientation_wxyz(t_true)[:, s.index, :]
            gyro = self.motion.angular_rate_rps(t_true)[:, s.index, :]
            quat_q14 = np.clip(np.rint(quat * QUAT_Q14_ONE), -INT16_FULL_SCALE, INT16_FULL_SCALE).astype(np.int16)
            gyro_counts = np.clip(np.rint(gyro / self.gyro_scale_rps_per_lsb), -INT16_FULL_SCALE,
                                  INT16_FULL_SCALE).astype(np.int16)
        records = [
            BatchRecord(s.sensor_id, self._boot_index, s.next_counter + i, latched[i:i + per_batch],
                        t_true[i:i + per_batch], acc[i:i + per_batch], counts[i:i + per_batch], flags,
                        *(None if a is None else a[i:i + per_batch] for a in (quat, gyro, quat_q14, gyro_counts)))
            for i in range(0, n, per_batch)
        ]
        self.truth.batches.extend(records)
        s.next_j += n
        s.next_counter += n
        return records

    def _radio(self, s: _Sensor, records: list[BatchRecord]) -> None:
        """Decide each batch's radio fate (three uniform draws per batch, always, for determinism)."""
        cfg = self.config
        u = s.radio_rng.random((len(records), 3))
        for rec, (u_loss, u_burst, u_jitter) in zip(records, u):
            done = float(rec.t_true_s[-1])
            if u_loss < cfg.radio_loss:
                rec.fate = Fate.RADIO_DROPPED
                heapq.heappush(self._events, (done, _DROP, s.sensor_id, rec.first_counter, None))
                continue
            arrival = done + cfg.latency_s - cfg.jitter_s * math.log1p(-u_jitter)
            if u_burst < cfg.burst_probability:
                arrival += cfg.burst_duration_s
            arrival = max(arrival, s.radio_free_s)
            s.radio_free_s = arrival
            heapq.heappush(self._events, (arrival, _BATCH, s.sensor_id, rec.first_counter, rec))

    # ------------------------------------------------------------------ output
    def _send_batch(self, rec: BatchRecord) -> None:
        s = self._sensors[rec.sensor_id]
        period_q8 = round(self.config.tick_rate_hz * 256 / s.rate_hz)
        msg = SampleBatch(rec.sensor_id, rec.flags, rec.first_counter % SEQ_MODULUS, int(rec.ticks[0]),
                          period_q8, scale_for_range(s.range_g), rec.counts, rec.quat_q14, rec.gyro_counts,
                          self.gyro_scale_rps_per_lsb if rec.gyro_counts is not None else 0.0)
        self._send(msg, rec)

    def _send_beacon(self, echo_command_id: int) -> None:
        t = self._event_time_s
        ticks = int(self.clock.counter(self.clock.ticks_since_boot(t - self.boot_time_s)))
        self.truth.beacon_log.append((t, ticks, self._beacon_counter, self._boot_index))
        self._send(ClockSync(ticks, self._beacon_counter, echo_command_id))
        self._beacon_counter += 1

    def _hello(self) -> Hello:
        cfg = self.config
        return Hello(cfg.firmware_version, cfg.serial, self.boot_id, cfg.tick_rate_hz, cfg.supported_rates_hz,
                     cfg.supported_ranges_g,
                     tuple(SensorInfo(s.sensor_id, int(self._sensor_kind), s.rate_hz, s.range_g)
                           for s in self._sensors))

    @property
    def _sensor_kind(self) -> SensorKind:
        if self.config.orientation:
            return SensorKind.ACCELEROMETER | SensorKind.ORIENTATION | SensorKind.ANGULAR_RATE
        return SensorKind.ACCELEROMETER

    @property
    def gyro_scale_rps_per_lsb(self) -> float:
        """rad/s per count of the angular-rate channel, rounded to float32 as on the wire."""
        return float(np.float32(math.radians(self.config.gyro_range_dps) / INT16_FULL_SCALE))

    def _status(self) -> Status:
        t = self._event_time_s
        uptime_s = t - self.boot_time_s
        flags = StationFlags(0)
        if self._streaming:
            flags |= StationFlags.STREAMING
        if self._calibrating:
            flags |= StationFlags.CALIBRATING
        if t < self._identify_until_s:
            flags |= StationFlags.IDENTIFYING
        buffered = sum(len(e[4].ticks) for e in self._events if e[1] == _BATCH and e[4].t_true_s[-1] <= t)
        rssi = self._misc_rng.integers(-3, 4, len(self._sensors))
        links = tuple(
            SensorLink(s.sensor_id, int(-45 - 4 * s.index + rssi[i]),
                       int(max(0, 100 - s.index - uptime_s / 600.0)))
            for i, s in enumerate(self._sensors)
        )
        return Status(int(flags), 100, 5000, int(uptime_s * 1000) % SEQ_MODULUS, buffered, self._radio_drops,
                      self._host_frames_rejected, links)

    def _send(self, message: Message, batch: BatchRecord | None = None) -> None:
        msg_type, payload = message_type_and_payload(message)
        frame = frame_payload(msg_type, payload, self.config.station_id, self._seq)
        record = FrameRecord(self._seq, self._boot_index, int(msg_type), self._event_time_s,
                             self.bytes_out + len(self._out), len(frame), batch=batch)
        if batch is not None:
            batch.frame = len(self.truth.frame_log)
        self.truth.frame_log.append(record)
        self._out_frames.append(record)
        self._out += frame
        self._seq = (self._seq + 1) % SEQ_MODULUS

    def _flush_wire(self) -> bytes:
        """Damage bytes as the wire would, settle the fate of the frames in this chunk, hand the bytes out."""
        data = self._out
        p = self.config.byte_corruption
        damaged = np.zeros(0, np.int64)
        if p > 0 and data:
            damaged = np.flatnonzero(self._wire_hit_rng.random(len(data)) < p)
            if damaged.size:
                arr = np.frombuffer(data, np.uint8).copy()
                arr[damaged] ^= self._wire_xor_rng.integers(1, 256, damaged.size).astype(np.uint8)
                data = bytearray(arr.tobytes())
        base = self.bytes_out
        for frame in self._out_frames:
            lo, hi = frame.byte_offset - base - 1, frame.byte_offset - base + frame.n_bytes
            hit = np.searchsorted(damaged, hi) - np.searchsorted(damaged, max(lo, 0)) > 0
            if lo < 0 and self._last_wire_byte_damaged:
                hit = True
            frame.intact = not hit
            if frame.batch is not None:
                frame.batch.fate = Fate.DELIVERED if frame.intact else Fate.WIRE_CORRUPTED
        if data:
            self._last_wire_byte_damaged = bool(damaged.size and damaged[-1] == len(data) - 1)
        self.bytes_out += len(data)
        self._out = bytearray()
        self._out_frames = []
        return bytes(data)

    # ------------------------------------------------------------------ introspection
    @property
    def streaming(self) -> bool:
        return self._streaming

    @property
    def host_bytes_received(self) -> int:
        """Host->station bytes received since boot (lets a test wait until its command has arrived)."""
        return self._host_decoder.stats.bytes_received

    @property
    def seconds_since_boot(self) -> float:
        return self.now_s - self.boot_time_s

