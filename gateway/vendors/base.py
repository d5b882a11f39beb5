"""What every vendor-library station shares: the library calls back with samples on its own thread; this reader
stamps arrivals, batches every ``batch_s``, maps device ticks onto the gateway clock with the project's
lower-envelope `ClockEstimator`, rebuilds sample counters from the ticks at the nominal period (vendor messages
carry no counter, so a gap of k periods counts k-1 lost samples), reports clock points for the recording's
offline re-fit, and delivers the same `SampleBlock`s as the project's own stations. A tick count going backwards
is a device reset: a new clock epoch."""
from __future__ import annotations

import logging
import threading
import time
from collections import deque
from typing import Any

import numpy as np

from gateway.clock import ClockEstimator
from gateway.links import LinkError
from gateway.station import SampleBlock
from gateway.stats import SensorStats

log = logging.getLogger(__name__)
STALE_AFTER_S = 0.5
RATE_LEARN_SAMPLES = 20


class CallbackStationReader:
    """Base of the vendor readers (same surface as `gateway.station.StationReader`: ``start``, ``stop``,
    ``name``, ``source``, ``status``, ``command``). Subclasses implement :meth:`_connect` (open the device
    through its library, learn its identity, register :meth:`_on_sample`) and :meth:`_disconnect`."""

    transport = "serial"
    device = "device"
    has_device_clock = True

    def __init__(self, source: str, sink: Any, tick_hz: float, *, reconnect_interval_s: float = 0.5,
                 clock_window_s: float = 60.0, lock_after_s: float = 30.0, batch_s: float = 0.02) -> None:
        self.source, self.sink, self.tick_hz = source, sink, tick_hz
        self.reconnect_interval_s, self.batch_s = reconnect_interval_s, batch_s
        self.clock = ClockEstimator(window_s=clock_window_s, lock_after_s=lock_after_s)
        self.stats = SensorStats(0)
        self.identity: str | None = None  # serial number / device name, once the device answered
        self.link_state = "connecting"
        self.link_error: str | None = None
        self.epoch = 0
        self.period_ticks: float | None = None  # known from the device, else learned from the first samples
        self._queue: deque[tuple[int, float, np.ndarray]] = deque()
        self._t0: int | None = None
        self._last: int | None = None
        self._last_arrival: float | None = None
        self._connected = False
        self.reconnects = 0
        self.internal_errors = 0
        self._ever_connected = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def name(self) -> str:
        return f"{self.device.lower().replace('-', '')}-{self.identity}" if self.identity else self.source

    # -- subclass hooks ---------------------------------------------------------------------------------------
    def _connect(self) -> None:
        """Open the device; raise LinkError with the reason when it cannot be used."""
        raise NotImplementedError

    def _disconnect(self) -> None:
        raise NotImplementedError

    def _extra_status(self) -> dict[str, Any]:
        return {}

    # -- thread -----------------------------------------------------------------------------------------------
    def start(self) -> "CallbackStationReader":
        self._thread = threading.Thread(target=self._run, name=f"gw-{self.device}-{self.source}", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 2.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
        if self._connected:
            self._disconnect()
            self._connected = False
        self.link_state = "stopped"

    def _run(self) -> None:
        while not self._stop.is_set():
            if not self._connected:
                try:
                    self._connect()
                except LinkError as exc:
                    changed, self.link_error = str(exc) != self.link_error, str(exc)
                    if changed:
                        self.sink.on_station_event(self.source, "alarm", f"cannot open link: {exc}")
                    self._stop.wait(self.reconnect_interval_s)
                    continue
                self._connected, self.link_error = True, None
                self.reconnects += self._ever_connected
                self._ever_connected = True
                self.sink.on_station_event(self.name, "info", f"{self.device} {self.identity} open on {self.source}")
            self._stop.wait(self.batch_s)
            try:
                self._flush()
            except Exception:  # a bug downstream must not stop acquisition
                self.internal_errors += 1
                log.exception("%s: processing failed", self.name)
            fresh = self._last_arrival is not None and time.monotonic() - self._last_arrival < STALE_AFTER_S
            self.link_state = "streaming" if fresh else "stale"

    # -- samples ----------------------------------------------------------------------------------------------
    def _on_sample(self, ticks: int, acc_g: np.ndarray, gyro_rps: np.ndarray | None = None,
                   quat_wxyz: np.ndarray | None = None) -> None:
        """One sample from the library's thread: device ticks (already unwrapped), acceleration (g) and, from a
        device that reports them, angular rate (rad/s) and orientation (sensor -> device earth, Z up)."""
        now = time.monotonic()
        self._last_arrival = now
        self._queue.append((int(ticks), now, np.asarray(acc_g, np.float32),
                            None if gyro_rps is None else np.asarray(gyro_rps, np.float32),
                            None if quat_wxyz is None else np.asarray(quat_wxyz, np.float32)))

    def _flush(self) -> None:
        if self.period_ticks is None and len(self._queue) < RATE_LEARN_SAMPLES:
            return
        items = [self._queue.popleft() for _ in range(len(self._queue))]
        if not items:
            return
        ticks = np.array([i[0] for i in items], np.int64)
        arrival = np.array([i[1] for i in items])
        acc = np.stack([i[2] for i in items]).astype(np.float32)
        gyro, quat = (_optional_column([i[k] for i in items], width) for k, width in ((3, 3), (4, 4)))
        if self._last is not None and ticks[0] < self._last:
            self.epoch += 1
            self.clock.restart()
            self._t0 = None
            self.stats.restart_counter()
            self.sink.on_station_event(self.name, "warning", f"{self.device} clock went backwards: new clock epoch")
        if self._t0 is None:
            self._t0 = int(ticks[0])
        if self.period_ticks is None:
            self.period_ticks = float(np.median(np.diff(ticks))) if len(ticks) > 1 else self.tick_hz / 100.0
        self.stats.nominal_hz = round(self.tick_hz / self.period_ticks, 3)
        self._last = int(ticks[-1])
        rel = ticks - self._t0
        device_s = rel / self.tick_hz
        for d, a in zip(device_s, arrival):
            self.clock.add(float(d), float(a))
        on_clock_point = getattr(self.sink, "on_clock_point", None)
        if on_clock_point is not None:  # raw clock evidence for the recording's offline re-fit
            on_clock_point(self.name, self.epoch, int(ticks[-1] % (1 << 32)), int(rel[-1]), float(arrival[-1]),
                           self.tick_hz)
        counter = np.round(rel / self.period_ticks).astype(np.int64)
        for start, run in _runs(counter):
            self.stats.on_batch(int(counter[start]) % (1 << 32), run, float(arrival[start + run - 1]))
        t_host = self.stats.monotonic_host_times(self.clock.to_host(device_s),  # never steps back (issue 22)
                                                 self.period_ticks / self.tick_hz)
        self.sink.on_samples(SampleBlock(
            station=self.name, sensor=0, nominal_hz=self.stats.nominal_hz, clock_locked=self.clock.state.locked,
            epoch=self.epoch, counter=counter.astype(np.uint32), raw_ticks=(ticks % (1 << 32)).astype(np.uint32),
            ticks=rel.astype(np.float64), arrival_s=arrival, t_host_s=t_host, acc_g=acc, quat_wxyz=quat,
            gyro_rps=gyro))

    # -- gateway surface --------------------------------------------------------------------------------------
    def command(self, *args: Any, **kwargs: Any) -> dict:
        raise LinkError(f"{self.name}: a {self.device} takes no Courtside station commands "
                        "(configure it with the vendor's software)")

    def status(self, now_s: float | None = None, rate_window_s: float = 1.0) -> dict:
        now_s = time.monotonic() if now_s is None else now_s
        self.stats.update_rate(now_s, rate_window_s)
        clock = self.clock.state.as_dict()
        clock["epoch"] = self.epoch
        return {"station": self.name, "source": self.source, "transport": self.transport, "link": self.link_state,
                "device": self.device, "device_clock": self.has_device_clock, "station_serial": self.identity,
                "tick_hz": self.tick_hz, "link_error": self.link_error, "reconnects": self.reconnects,
                "internal_errors": self.internal_errors, "clock": clock,
                "sensors": [self.stats.as_dict()], **self._extra_status()}


def _optional_column(values: list[np.ndarray | None], width: int) -> np.ndarray | None:
    """(N, width) float32 of a channel some samples carry (NaN rows for the others), None when none does."""
    if all(v is None for v in values):
        return None
    return np.stack([np.full(width, np.nan, np.float32) if v is None else v for v in values]).astype(np.float32)


def _runs(counter: np.ndarray) -> list[tuple[int, int]]:
    """(start, length) of runs of consecutive counters, so each run is one `SensorStats.on_batch`."""
    breaks = np.flatnonzero(np.diff(counter) != 1) + 1
    starts = np.r_[0, breaks]
    ends = np.r_[breaks, len(counter)]
    return list(zip(starts.tolist(), (ends - starts).tolist()))
