"""An emulated base station (the firmware, in Python) with pty, emu:// and fake-HID transports.

Core: `BaseStation(StationConfig(...), motion)` -- `write(bytes)`, `advance(seconds) -> bytes`, `unplug()`,
`replug()`, ground truth in `.truth` (`samples()`, `frames()`, `beacons()` as numpy arrays).
Transports: `EmulatorLink` (thread-safe handle, manual or wall-clock time) under `PtyTransport`, the `emu://`
pyserial URL (`protocol_emu`), and `FakeHidBus` (a stand-in `hid` module; the 64-byte report framing and the
host-side `HidapiTransport` are in `firmware_protocol.hid`).
"""
from .clock import TICK_MODULUS, CrystalClock
from .ground_truth import BeaconTruth, Fate, FrameTruth, SampleTruth
from .hid_transport import FakeHidBus, FakeHidDevice
from .link import EmulatorLink
from .motion import MocapSource, MotionSource, StillSource, TraceSource
from .pty_transport import PtyTransport
from .station import BaseStation, StationConfig

__all__ = [
    "TICK_MODULUS", "BaseStation", "BeaconTruth", "CrystalClock", "EmulatorLink", "FakeHidBus", "FakeHidDevice",
    "Fate", "FrameTruth", "MocapSource", "MotionSource", "PtyTransport", "SampleTruth",
    "StationConfig", "StillSource", "TraceSource",
]
