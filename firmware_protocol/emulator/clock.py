"""The station's crystal: true (host-reference) seconds <-> device ticks.

Why a separate model: tests score time alignment against it, so offset, drift and wrap are explicit numbers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TICK_MODULUS = 1 << 32


@dataclass(frozen=True, slots=True)
class CrystalClock:
    """Free-running u32 tick counter started at `offset_ticks` when the station boots.

    A crystal `drift_ppm` fast ticks `tick_rate_hz * (1 + drift_ppm * 1e-6)` times per true second.
    All `*_since_boot` values are unwrapped float64 ticks counted from boot (offset excluded)."""
    tick_rate_hz: int = 1_000_000
    offset_ticks: int = 0
    drift_ppm: float = 0.0

    def __post_init__(self) -> None:
        if self.tick_rate_hz <= 0:
            raise ValueError(f"tick rate must be positive, got {self.tick_rate_hz}")
        if not 0 <= self.offset_ticks < TICK_MODULUS:
            raise ValueError(f"tick offset must be a u32, got {self.offset_ticks}")

    @property
    def true_rate_hz(self) -> float:
        """Ticks per true second."""
        return self.tick_rate_hz * (1.0 + self.drift_ppm * 1e-6)

    def ticks_since_boot(self, seconds_since_boot: float | np.ndarray) -> float | np.ndarray:
        return np.multiply(seconds_since_boot, self.true_rate_hz)

    def seconds_since_boot(self, ticks_since_boot: float | np.ndarray) -> float | np.ndarray:
        return np.divide(ticks_since_boot, self.true_rate_hz)

    def counter(self, ticks_since_boot: float | np.ndarray) -> int | np.ndarray:
        """The u32 register value (latched, i.e. floored) at an unwrapped since-boot tick count."""
        raw = np.floor(np.add(ticks_since_boot, self.offset_ticks)).astype(np.int64) % TICK_MODULUS
        return int(raw) if np.ndim(raw) == 0 else raw
