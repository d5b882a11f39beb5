"""An emulated base station (the firmware, in Python) with pty, emu:// and fake-HID transports.

Core: `BaseStation(StationConfig(...), motion)` -- `write(bytes)`, `advance(seconds) -> bytes`, `unplug()`,
`replug()`, ground truth in `.truth` (`samples()`, `frames()`, `beacons()` as numpy arrays).
"""
from .clock import TICK_MODULUS, CrystalClock
from .ground_truth import BeaconTruth, Fate, FrameTruth, SampleTruth
from .motion import MocapSource, MotionSource, StillSource, TraceSource
from .station import BaseStation, StationConfig

__all__ = [
    "TICK_MODULUS", "BaseStation", "BeaconTruth", "CrystalClock", "Fate", "FrameTruth", "MocapSource",
    "MotionSource", "SampleTruth", "StationConfig", "StillSource", "TraceSource",
]
