"""Per-sensor link statistics: received/lost/duplicate samples from counters, live rate, battery, RSSI.

Why counters and not arrival times for loss: each sample carries a u32 per-sensor counter, so a gap is exact
(``first_counter - expected``), independent of radio batching or host scheduling. Rates are measured over
wall-clock windows of at least ``rate_window_s`` so a status read at any moment gives a stable number.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

COUNTER_MODULUS = 1 << 32
_HALF = COUNTER_MODULUS // 2
MIN_STEP_OF_PERIOD = 0.1  # a held sample follows its predecessor by at least a tenth of the sample period


@dataclass
class SensorStats:
    """Counters for one sensor of one station (reset only when the gateway restarts)."""

    sensor: int
    nominal_hz: float = 0.0
    received: int = 0
    lost: int = 0  # samples skipped by the counter (radio loss)
    duplicates: int = 0  # counter went backwards (retransmission / reordering): still delivered
    counter_resets: int = 0  # counter restarted (station reboot)
    battery_pct: int | None = None
    rssi_dbm: int | None = None
    last_t_host_s: float | None = None
    host_time_held: int = 0  # samples whose host time was held after the previous one (clock re-fit stepped back)
    rate_hz: float = 0.0
    _expected: int | None = None
    _rate_mark: tuple[float, int] | None = field(default=None, repr=False)

    def on_batch(self, first_counter: int, n: int, arrival_s: float) -> None:
        """Account for a batch of ``n`` consecutive samples starting at ``first_counter``."""
        if self._expected is not None:
            gap = (first_counter - self._expected) % COUNTER_MODULUS
            if 0 < gap < _HALF:
                self.lost += gap
            elif gap >= _HALF:
                self.duplicates += min(n, COUNTER_MODULUS - gap)
        end = (first_counter + n) % COUNTER_MODULUS
        if self._expected is None or (end - self._expected) % COUNTER_MODULUS < _HALF:
            self._expected = end
        self.received += n
        if self._rate_mark is None:
            self._rate_mark = (arrival_s, self.received - n)

    def monotonic_host_times(self, t_host_s: np.ndarray, period_s: float) -> np.ndarray:
        """``t_host_s`` made strictly increasing after every earlier sample of this sensor, and remembered.

        Why (issue 22): the host time of a sample comes from the station's clock estimate, which is re-fitted as
        it warms up and restarted at a new clock epoch; either stepped a stream's time back by 2-16 ms. Consumers
        (engine.stream, exports) need each stream's time to increase, so a sample the estimate puts less than
        a tenth of a sample period (``period_s``) after its predecessor is held there, and the next ones follow
        at that spacing until the estimate passes them (a slew, as NTP does, never a step back; each held sample
        is counted in ``host_time_held``). A tenth, not more: an emulated station at 4x real time delivers its
        samples a quarter period apart on the host clock, and the hold must still catch up. The recording keeps each sample's raw ticks, arrival and epoch, so the
        offline re-fit (``t_realigned_s``) is unaffected."""
        t = np.asarray(t_host_s, dtype=float)
        min_step_s = MIN_STEP_OF_PERIOD * period_s if period_s > 0 else 1e-6
        floor = -np.inf if self.last_t_host_s is None else self.last_t_host_s + min_step_s
        steps = min_step_s * np.arange(len(t))
        held = np.maximum.accumulate(np.maximum(t - steps, floor)) + steps
        self.host_time_held += int(np.count_nonzero(held > t))
        if len(held):
            self.last_t_host_s = float(held[-1])
        return held

    def restart_counter(self) -> None:
        """The station rebooted: its counters restart, so do not count the jump as loss."""
        if self._expected is not None:
            self.counter_resets += 1
        self._expected = None

    def update_rate(self, now_s: float, rate_window_s: float) -> None:
        """Refresh ``rate_hz`` once at least ``rate_window_s`` has passed since the last refresh."""
        if self._rate_mark is None:
            self.rate_hz = 0.0
            return
        t0, n0 = self._rate_mark
        if now_s - t0 >= rate_window_s:
            self.rate_hz = (self.received - n0) / (now_s - t0)
            self._rate_mark = (now_s, self.received)

    @property
    def loss_pct(self) -> float:
        total = self.received + self.lost
        return 100.0 * self.lost / total if total else 0.0

    def as_dict(self) -> dict:
        return {
            "sensor": self.sensor, "nominal_hz": self.nominal_hz, "rate_hz": round(self.rate_hz, 3),
            "received": self.received, "lost": self.lost, "duplicates": self.duplicates,
            "counter_resets": self.counter_resets, "loss_pct": round(self.loss_pct, 4),
            "battery_pct": self.battery_pct, "rssi_dbm": self.rssi_dbm, "last_t_host_s": self.last_t_host_s,
            "host_time_held": self.host_time_held,
        }
