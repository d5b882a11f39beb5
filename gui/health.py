"""Pure (Qt-free) health rules: sync colour per station and alarm conditions from a gateway status snapshot.

Kept separate from the widgets so the thresholds are testable with plain dicts and documented in one place."""
from __future__ import annotations

import shutil
from dataclasses import dataclass
from enum import Enum
from typing import Any


class Sync(str, Enum):
    GREEN = "green"   # clock locked, residual small
    AMBER = "amber"   # warming up, or residual elevated
    RED = "red"       # link lost/stale or residual too large to trust sample times


# The gateway's residual is the median height of per-bin delay minima above the fitted clock envelope
# (gateway/clock.py): a few ms on a radio link with ms jitter. Green while it stays under half a sample period
# at 100 Hz; beyond 20 ms, two samples could be swapped in time, so the mapping is not trusted.
SYNC_GREEN_RESIDUAL_S = 0.005
SYNC_AMBER_RESIDUAL_S = 0.020
LOW_BATTERY_PCT = 20  # per-sensor battery %, as the stations report it in STATUS (gateway key battery_pct)
SENSOR_SILENT_S = 1.0
LOW_DISK_BYTES = 1 << 30
CAMERA_SLOW_FRACTION = 0.5  # the gateway's camera delivering under half its nominal rate (CPU starved, USB)
CAMERA_MIN_FRAMES = 30  # ... once it has run long enough for a rate


def sync_status(station: dict[str, Any]) -> Sync:
    """Traffic light for one station status (docs/gateway.md "Station status")."""
    if station.get("link") in ("lost", "stale", "connecting"):
        return Sync.RED
    clock = station.get("clock") or {}
    residual = abs(float(clock.get("residual_s") or 0.0))
    if not clock.get("locked"):
        return Sync.AMBER
    if residual < SYNC_GREEN_RESIDUAL_S:
        return Sync.GREEN
    return Sync.AMBER if residual < SYNC_AMBER_RESIDUAL_S else Sync.RED


SENSOR_LOSS_RED_PCT = 5.0  # a sensor losing this share of its packets is red whatever its station's clock


def sync_reason(station: dict[str, Any]) -> str:
    """The sync light in words, for its cell: the colour says how good, this says why (a cell reading "green" on
    green said nothing)."""
    link = station.get("link")
    if link in ("lost", "stale", "connecting"):
        return f"link {link}"
    clock = station.get("clock") or {}
    if not clock.get("locked"):
        return "warming up"
    residual = abs(float(clock.get("residual_s") or 0.0))
    return "locked" if residual < SYNC_GREEN_RESIDUAL_S else f"residual {1e3 * residual:.1f} ms"


def sensor_sync(station: dict[str, Any], sensor: dict[str, Any]) -> tuple[Sync, str]:
    """A sensor's light and its reason: its station's, or red when it loses too many packets."""
    loss = float(sensor.get("loss_pct") or 0.0)
    if loss >= SENSOR_LOSS_RED_PCT:
        return Sync.RED, f"loss {loss:.1f} %"
    return sync_status(station), sync_reason(station)


@dataclass(frozen=True)
class Alarm:
    """One alarm condition; ``key`` identifies it so a banner is shown once and cleared when it goes away."""

    key: str
    level: str  # "warning" | "alarm"
    message: str


def status_alarms(status: dict[str, Any], disk_path: str | None = None, was_locked: set[str] | None = None) -> list[Alarm]:
    """Alarm conditions present in one status snapshot.

    ``was_locked``: stations whose clock has been locked before (sync *lost* differs from still warming up);
    it is updated in place."""
    alarms: list[Alarm] = []
    now = status.get("t_host_s")
    for st in status.get("stations", []):
        sid = str(st.get("station"))
        link = st.get("link")
        if link in ("lost", "stale"):
            alarms.append(Alarm(f"link:{sid}", "alarm", f"station {sid}: link {link}"))
        clock = st.get("clock") or {}
        if was_locked is not None:
            if clock.get("locked"):
                was_locked.add(sid)
            elif sid in was_locked:
                alarms.append(Alarm(f"sync:{sid}", "alarm", f"station {sid}: clock sync lost"))
        if sync_status(st) is Sync.RED and link == "streaming":
            alarms.append(Alarm(f"residual:{sid}", "warning",
                                f"station {sid}: clock residual {1e3 * float(clock.get('residual_s') or 0):.1f} ms"))
        for sensor in st.get("sensors", []):
            name = f"{sid}/{sensor.get('sensor')}"
            battery = sensor.get("battery_pct")
            if battery is not None and float(battery) < LOW_BATTERY_PCT:
                alarms.append(Alarm(f"battery:{name}", "warning", f"sensor {name}: low battery {float(battery):.0f} %"))
            last = sensor.get("last_t_host_s")
            if now is not None and link == "streaming" and (last is None or float(now) - float(last) > SENSOR_SILENT_S):
                alarms.append(Alarm(f"lost:{name}", "alarm", f"sensor {name}: no data"))
    camera = status.get("camera")  # the gateway's camera health (docs/gateway.md "Config file")
    if camera:
        if camera.get("state") in ("failed", "ended"):
            alarms.append(Alarm("camera", "alarm", f"camera {camera.get('state')}"
                                + (f": {camera['error']}" if camera.get("error") else "")))
        elif camera.get("state") == "running" and camera.get("frames", 0) > CAMERA_MIN_FRAMES and \
                float(camera.get("fps") or 0.0) < CAMERA_SLOW_FRACTION * float(camera.get("nominal_fps") or 0.0):
            alarms.append(Alarm("camera", "warning", f"camera at {float(camera['fps']):.1f} fps "
                                f"(nominal {float(camera['nominal_fps']):.0f})"))
    if disk_path:
        try:
            free = shutil.disk_usage(disk_path).free
        except OSError:
            free = None
        if free is not None and free < LOW_DISK_BYTES:
            alarms.append(Alarm("disk", "warning", f"low disk space: {free / 1e9:.2f} GB free at {disk_path}"))
    return alarms
