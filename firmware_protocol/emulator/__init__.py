"""An emulated base station (the firmware, in Python) with pty, emu:// and fake-HID transports.

Core: `BaseStation(StationConfig(...), motion)` -- `write(bytes)`, `advance(seconds) -> bytes`, `unplug()`,
`replug()`, ground truth in `.truth` (`samples()`, `frames()`, `beacons()` as numpy arrays).
Transports: `EmulatorLink` (thread-safe handle, manual or wall-clock time) under `PtyTransport`, the `emu://`
pyserial URL (`protocol_emu`), and `FakeHidBus` (a stand-in `hid` module; the 64-byte report framing and the
host-side `HidapiTransport` are in `firmware_protocol.hid`).

Every other emulator and fault tool lives beside it (issue 19), imported by name only when asked for, so the
gateway's own code never loads them: `stations` (emulated base stations on ptys replaying mocap as worn
sensors: `courtside gateway --emulate`, the demo, tests), `virtual_time` (a station through a `StationReader` in
virtual time, scored against ground truth), `ximu3_device` / `shimmer_device` on `pty_device` (the vendor
devices the x-IMU3 and Shimmer3 libraries open), `faultfs` (a file system that fails on cue: full disk, EIO).
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
