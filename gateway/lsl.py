"""Lab Streaming Layer out of the gateway: one LSL outlet per station (pylsl, liblsl ships in its wheel).

Stream layout (the same as `courtside gateway export --xdf`, gateway.xdf): name ``"<gateway> <station>"``,
type ``Accelerometer``, irregular rate (each sample carries its own time stamp), float32 channels
``sensor, acc_x_g, acc_y_g, acc_z_g``; a station with sensors that stream orientation or angular rate also gets
a second outlet ``"<gateway> <station> orientation"``, type ``Orientation``, channels `ORIENTATION_CHANNELS`
(``sensor, quat_w .. quat_z`` sensor -> device earth Z up, ``gyro_x_rps .. gyro_z_rps``; NaN where the sensor
has no such channel), created on the first such sample. One station's sensors arrive in separate per-sensor batches with their own
latch times, so a row per sample with the sensor index as first channel keeps every sample at its true time;
split by the ``sensor`` channel on the receiving side.

Clock: samples are stamped on the gateway clock (host monotonic); LSL wants ``pylsl.local_clock()``. The offset
between the two is measured by reading both back to back (the tightest of several reads) and refreshed every
``refresh_s``; on Linux both are CLOCK_MONOTONIC and the offset is ~0, but nothing relies on that.

Staying on this machine: liblsl announces and resolves streams by UDP multicast/broadcast by default. Unless
publishing beyond the machine is asked for explicitly (``scope="network"``), :func:`use_loopback_config` points
liblsl at an ``lsl_api.cfg`` (through ``LSLAPICFG``, before liblsl is first loaded) with ``ResolveScope =
machine``, ``MachineAddresses = {127.0.0.1}``, ``KnownPeers = {127.0.0.1}`` and IPv6 off."""
from __future__ import annotations

import os
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import CourtsideError

LOOPBACK_CONFIG = """; Courtside: keep liblsl on this machine (no multicast, no non-loopback address)
[ports]
IPv6 = disable

[multicast]
ResolveScope = machine
MachineAddresses = {127.0.0.1}

[lab]
KnownPeers = {127.0.0.1}
"""
CHANNELS = ("sensor", "acc_x_g", "acc_y_g", "acc_z_g")
ORIENTATION_CHANNELS = ("sensor", "quat_w", "quat_x", "quat_y", "quat_z", "gyro_x_rps", "gyro_y_rps", "gyro_z_rps")
# stream kind -> (name suffix, LSL type, channels); units and channel types per label in `channel_meta`
LAYOUTS = {"acc": ("", "Accelerometer", CHANNELS), "orientation": (" orientation", "Orientation", ORIENTATION_CHANNELS)}


def channel_meta(label: str) -> tuple[str, str]:
    """(unit, LSL channel type) of a channel label."""
    if label == "sensor":
        return "index", "Index"
    if label.startswith("quat_"):
        return "normalized", "Orientation"
    if label.startswith("gyro_"):
        return "rad/s", "AngularVelocity"
    return "g", "Acceleration"


def orientation_rows(sensor: int, n: int, quat_wxyz: np.ndarray | None, gyro_rps: np.ndarray | None) -> np.ndarray:
    """(n, 8) float rows of the orientation stream: sensor index, quaternion, angular rate (NaN when absent)."""
    quat = np.full((n, 4), np.nan) if quat_wxyz is None else np.asarray(quat_wxyz, float).reshape(n, 4)
    gyro = np.full((n, 3), np.nan) if gyro_rps is None else np.asarray(gyro_rps, float).reshape(n, 3)
    return np.column_stack([np.full(n, float(sensor)), quat, gyro])
SCOPES = ("machine", "network")


def use_loopback_config(directory: str | Path | None = None) -> Path:
    """Write the loopback ``lsl_api.cfg`` and point ``LSLAPICFG`` at it; must run before pylsl loads liblsl.
    Refuses when liblsl is already loaded with another configuration (it reads its config once)."""
    path = Path(directory or tempfile.gettempdir()) / "courtside-lsl_api.cfg"
    if not path.is_file() or path.read_text() != LOOPBACK_CONFIG:
        path.write_text(LOOPBACK_CONFIG)
    current = os.environ.get("LSLAPICFG")
    if "pylsl" in __import__("sys").modules and current != str(path):
        raise CourtsideError("liblsl was loaded before the loopback LSL configuration was set: it could announce "
                             "streams beyond this machine; set LSLAPICFG first")
    os.environ["LSLAPICFG"] = str(path)
    return path


def _pylsl(scope: str) -> Any:
    if scope not in SCOPES:
        raise CourtsideError(f"unknown LSL scope {scope!r}; known: {', '.join(SCOPES)}")
    if scope == "machine":
        use_loopback_config()
    try:
        import pylsl
    except ImportError:
        raise CourtsideError("LSL needs pylsl: pip install 'courtside[lsl]'") from None
    return pylsl


class ClockMap:
    """Gateway clock (``time.monotonic``) -> LSL ``local_clock``: ``lsl = gateway + offset``."""

    def __init__(self, local_clock: Any, refresh_s: float = 10.0) -> None:
        self._local_clock = local_clock
        self.refresh_s = refresh_s
        self._measured_at = -np.inf
        self.offset_s = 0.0

    def measure(self, tries: int = 5) -> float:
        best = None
        for _ in range(tries):
            a = time.monotonic()
            lsl = self._local_clock()
            b = time.monotonic()
            if best is None or b - a < best[0]:
                best = (b - a, lsl - 0.5 * (a + b))
        self.offset_s = best[1]
        self._measured_at = time.monotonic()
        return self.offset_s

    def __call__(self, gateway_s: np.ndarray) -> np.ndarray:
        if time.monotonic() - self._measured_at > self.refresh_s:
            self.measure()
        return np.asarray(gateway_s, float) + self.offset_s


class LslPublisher:
    """A gateway sample sink: ``on_block(block)`` (a ``gateway.station.SampleBlock``) pushes the block's samples
    to its station's outlet, created on first use."""

    def __init__(self, gateway_name: str = "courtside-gateway", scope: str = "machine") -> None:
        self.pylsl = _pylsl(scope)
        self.gateway_name = gateway_name
        self.scope = scope
        self.clock = ClockMap(self.pylsl.local_clock)
        self._outlets: dict[tuple[str, str], Any] = {}
        self._lock = threading.Lock()
        self.samples_pushed = 0

    def stream_info(self, station: str, kind: str = "acc") -> Any:
        pylsl = self.pylsl
        suffix, lsl_type, labels = LAYOUTS[kind]
        info = pylsl.StreamInfo(f"{self.gateway_name} {station}{suffix}", lsl_type, len(labels),
                                pylsl.IRREGULAR_RATE, pylsl.cf_float32,
                                f"courtside/{self.gateway_name}/{station}{suffix.replace(' ', '/')}")
        channels = info.desc().append_child("channels")
        for label in labels:
            unit, channel_type = channel_meta(label)
            ch = channels.append_child("channel")
            ch.append_child_value("label", label)
            ch.append_child_value("unit", unit)
            ch.append_child_value("type", channel_type)
        info.desc().append_child_value("clock", "gateway clock (host monotonic) mapped to lsl local_clock")
        return info

    def outlet(self, station: str, kind: str = "acc") -> Any:
        with self._lock:
            if (station, kind) not in self._outlets:
                self._outlets[(station, kind)] = self.pylsl.StreamOutlet(self.stream_info(station, kind))
            return self._outlets[(station, kind)]

    def on_block(self, block: Any) -> None:
        n = len(block.acc_g)
        stamps = self.clock(block.t_host_s).tolist()
        rows = np.column_stack([np.full(n, float(block.sensor)), np.asarray(block.acc_g, float)])
        self.outlet(block.station).push_chunk(rows.astype(np.float32), stamps)
        if block.quat_wxyz is not None or block.gyro_rps is not None:
            rows = orientation_rows(block.sensor, n, block.quat_wxyz, block.gyro_rps)
            self.outlet(block.station, "orientation").push_chunk(rows.astype(np.float32), stamps)
        self.samples_pushed += n

    def close(self) -> None:
        with self._lock:
            self._outlets.clear()  # liblsl destroys an outlet when its last reference goes
