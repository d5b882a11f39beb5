"""An x-IMU3 (x-io Technologies) as a gateway station, read through the vendor's `ximu3` library.

Source ``ximu3:<serial port>[?baud=115200]``. The library opens the port exactly as for the hardware and calls
back on its own thread with each decoded inertial message; this reader stamps the arrival, batches messages
every ``batch_s`` and turns the device's microsecond time stamps into the gateway clock with the project's
lower-envelope `ClockEstimator` (the device clock is real, so the alignment is as good as for the project's own
stations). x-IMU3 messages carry no sample counter, so the counter is rebuilt from the time stamp at the nominal
rate (learned from the first samples): a gap of k periods counts k-1 lost samples. A time stamp going backwards is
a device reset: a new clock epoch. One x-IMU3 is one sensor (sensor 0); the station is named
``ximu3-<serial>`` from the device's answer to ``ping``."""
from __future__ import annotations

import threading
import time
from collections import deque
from typing import Any
from urllib.parse import parse_qs

import numpy as np

from gateway.clock import ClockEstimator
from gateway.links import LinkError
from gateway.station import SampleBlock
from gateway.stats import SensorStats

RATE_LEARN_SAMPLES = 20
STALE_AFTER_S = 0.5


class Ximu3Reader:
    """Same surface as `gateway.station.StationReader`: ``start``, ``stop``, ``name``, ``source``, ``status``,
    ``command`` (refused: the project's station commands do not apply)."""

    transport = "serial"

    def __init__(self, source: str, sink: Any, *, reconnect_interval_s: float = 0.5, clock_window_s: float = 60.0,
                 lock_after_s: float = 30.0, batch_s: float = 0.02) -> None:
        spec = source[len("ximu3:"):]
        path, _, query = spec.partition("?")
        self.source, self.path, self.sink = source, path, sink
        self.baud = int(parse_qs(query).get("baud", ["115200"])[0])
        self.reconnect_interval_s, self.batch_s = reconnect_interval_s, batch_s
        self.clock = ClockEstimator(window_s=clock_window_s, lock_after_s=lock_after_s)
        self.stats = SensorStats(0)
        self.device_name: str | None = None
        self.serial_number: str | None = None
        self.link_state = "connecting"
        self.link_error: str | None = None
        self.epoch = 0
        self.receive_errors = 0
        self._queue: deque[tuple[int, float, float, float, float]] = deque()
        self._t0_us: int | None = None
        self._last_us: int | None = None
        self._period_us: float | None = None
        self._conn: Any = None
        self._last_arrival: float | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()

    @property
    def name(self) -> str:
        return f"ximu3-{self.serial_number}" if self.serial_number else self.source

    # -- thread -----------------------------------------------------------------------------------------------
    def start(self) -> "Ximu3Reader":
        self._thread = threading.Thread(target=self._run, name=f"gw-ximu3-{self.path}", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 2.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
        if self._conn is not None:
            self._conn.close()
            self._conn = None
        self.link_state = "stopped"

    def _run(self) -> None:
        while not self._stop.is_set():
            if self._conn is None and not self._connect():
                self._stop.wait(self.reconnect_interval_s)
                continue
            self._stop.wait(self.batch_s)
            self._flush()
            fresh = self._last_arrival is not None and time.monotonic() - self._last_arrival < STALE_AFTER_S
            self.link_state = "streaming" if fresh else "stale"

    def _connect(self) -> bool:
        import ximu3

        conn = ximu3.Connection(ximu3.SerialConnectionConfig(self.path, self.baud, False))
        try:
            conn.open()
        except RuntimeError as exc:  # the library's "Unable to open Serial ...: <reason>"
            changed, self.link_error = str(exc) != self.link_error, str(exc)
            if changed:
                self.sink.on_station_event(self.source, "alarm", f"cannot open link: {exc}")
            return False
        ping = conn.ping()
        if ping is None or not ping.serial_number:  # None: no answer within the library's timeout
            conn.close()
            self.link_error = f"{self.path}: no answer to ping (not an x-IMU3?)"
            self.sink.on_station_event(self.source, "alarm", self.link_error)
            return False
        self.device_name, self.serial_number = ping.device_name, ping.serial_number
        conn.add_inertial_callback(self._on_inertial)
        conn.add_receive_error_callback(self._on_receive_error)
        self._conn, self.link_error = conn, None
        self.sink.on_station_event(self.name, "info", f"x-IMU3 {ping.device_name} {ping.serial_number} "
                                                      f"({ping.interface}) open on {self.path}")
        return True

    # -- library callbacks (its thread) -----------------------------------------------------------------------
    def _on_inertial(self, message: Any) -> None:
        now = time.monotonic()
        self._last_arrival = now
        self._queue.append((int(message.timestamp), now, message.accelerometer_x, message.accelerometer_y,
                            message.accelerometer_z))

    def _on_receive_error(self, error: Any) -> None:
        self.receive_errors += 1

    # -- batches ----------------------------------------------------------------------------------------------
    def _flush(self) -> None:
        if self._period_us is None and len(self._queue) < RATE_LEARN_SAMPLES:
            return  # the nominal rate is learned from the first samples
        items = [self._queue.popleft() for _ in range(len(self._queue))]
        if not items:
            return
        us = np.array([i[0] for i in items], np.int64)
        arrival = np.array([i[1] for i in items])
        acc = np.array([i[2:] for i in items], np.float32)
        if self._last_us is not None and us[0] < self._last_us:  # device reset: its clock started again
            self.epoch += 1
            self.clock.restart()
            self._t0_us, self._period_us = None, None
            self.stats.restart_counter()
            self.sink.on_station_event(self.name, "warning", "x-IMU3 time stamps went backwards: new clock epoch")
        if self._t0_us is None:
            self._t0_us = int(us[0])
        if self._period_us is None:
            self._period_us = float(np.median(np.diff(us))) if len(us) > 1 else 1e4
            self.stats.nominal_hz = round(1e6 / self._period_us, 3)
        self._last_us = int(us[-1])
        device_s = (us - self._t0_us) * 1e-6
        for d, a in zip(device_s, arrival):
            self.clock.add(float(d), float(a))
        on_clock_point = getattr(self.sink, "on_clock_point", None)
        if on_clock_point is not None:  # raw clock evidence for the recording's offline re-fit
            on_clock_point(self.name, self.epoch, int(us[-1] % (1 << 32)), int(us[-1] - self._t0_us),
                           float(arrival[-1]), 1e6)
        counter = np.round((us - self._t0_us) / self._period_us).astype(np.int64)
        for start, run in _runs(counter):
            self.stats.on_batch(int(counter[start]) % (1 << 32), run, float(arrival[start + run - 1]))
        t_host = self.clock.to_host(device_s)
        self.stats.last_t_host_s = float(t_host[-1])
        self.sink.on_samples(SampleBlock(
            station=self.name, sensor=0, nominal_hz=self.stats.nominal_hz, clock_locked=self.clock.state.locked,
            epoch=self.epoch, counter=counter.astype(np.uint32), raw_ticks=(us % (1 << 32)).astype(np.uint32),
            ticks=(us - self._t0_us).astype(np.float64), arrival_s=arrival, t_host_s=t_host, acc_g=acc))

    # -- gateway surface --------------------------------------------------------------------------------------
    def command(self, *args: Any, **kwargs: Any) -> dict:
        raise LinkError(f"{self.name}: an x-IMU3 takes no Courtside station commands (configure it with the "
                        "x-IMU3 GUI or ximu3 commands)")

    def status(self, now_s: float | None = None, rate_window_s: float = 1.0) -> dict:
        now_s = time.monotonic() if now_s is None else now_s
        self.stats.update_rate(now_s, rate_window_s)
        clock = self.clock.state.as_dict()
        clock["epoch"] = self.epoch
        return {"station": self.name, "source": self.source, "transport": self.transport, "link": self.link_state,
                "device": "x-IMU3", "device_clock": True, "device_name": self.device_name,
                "station_serial": self.serial_number, "tick_hz": 1e6, "link_error": self.link_error,
                "receive_errors": self.receive_errors, "clock": clock, "sensors": [self.stats.as_dict()]}


def _runs(counter: np.ndarray) -> list[tuple[int, int]]:
    """(start, length) of runs of consecutive counters, so each run is one `SensorStats.on_batch`."""
    breaks = np.flatnonzero(np.diff(counter) != 1) + 1
    starts = np.r_[0, breaks]
    ends = np.r_[breaks, len(counter)]
    return list(zip(starts.tolist(), (ends - starts).tolist()))
