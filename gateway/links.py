"""Byte links to base stations: serial ports (device paths, ptys, pyserial URLs such as ``emu://``) and HID.

Why a tiny `Link` protocol: the station reader only needs ``read`` (short timeout, b"" when idle), ``write`` and
``close``; every transport failure surfaces as `LinkError`, which the reader treats as "unplugged" and retries.

Discovery assumptions (documented in docs/gateway.md): Courtside base stations enumerate as USB CDC-ACM serial
with VID:PID ``1209:C0DE`` (pid.codes open-hardware VID) or as HID with the same VID:PID, and carry a USB serial
number that is stable across replugs.
"""
from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from typing import Any, Callable, Protocol

import serial
from serial.tools import list_ports

from engine.errors import CourtsideError

log = logging.getLogger(__name__)

STATION_VID = 0x1209
STATION_PID = 0xC0DE
READ_TIMEOUT_S = 0.05


class LinkError(CourtsideError, ConnectionError):
    """The link failed (cannot open, unplugged, I/O error). The message names the source."""


class Link(Protocol):
    source: str

    def read(self, max_bytes: int) -> bytes: ...

    def write(self, data: bytes) -> None: ...

    def close(self) -> None: ...


class SerialLink:
    """A serial port by path (``/dev/ttyACM0``, ``/dev/pts/7``) or any pyserial URL (``emu://...``, ``socket://``)."""

    transport = "serial"

    def __init__(self, source: str, baudrate: int = 921_600):
        self.source = source
        try:
            self._port = serial.serial_for_url(source, baudrate=baudrate, timeout=READ_TIMEOUT_S,
                                               write_timeout=1.0)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise LinkError(f"{source}: cannot open ({exc})") from exc

    def read(self, max_bytes: int = 65536) -> bytes:
        try:
            waiting = self._port.in_waiting
            return self._port.read(min(max(waiting, 1), max_bytes))
        except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
            # pyserial raises TypeError/AttributeError when the fd vanished under it on unplug
            raise LinkError(f"{self.source}: read failed ({exc})") from exc

    def write(self, data: bytes) -> None:
        try:
            self._port.write(data)
        except (serial.SerialException, OSError) as exc:
            raise LinkError(f"{self.source}: write failed ({exc})") from exc

    def close(self) -> None:
        try:
            self._port.close()
        except (serial.SerialException, OSError):
            pass


HID_READ_TIMEOUT_MS = int(READ_TIMEOUT_S * 1000)
_HID_IDS = re.compile(r"^([0-9a-fA-F]{4}):([0-9a-fA-F]{4})(?::(.+))?$")


class HidLink:
    """A base station on USB HID: ``hid:<hidapi path>`` or ``hid:VVVV:PPPP[:serial]`` (hex VID:PID).

    The 64-byte report framing is defined once in `firmware_protocol.hid` (`HidapiTransport`); this class adapts it to `Link`.
    ``hid_module`` is anything with the hidapi module API (``device()``, ``enumerate()``): the real ``hid``
    (hidapi) by default, `firmware_protocol.emulator.hid_transport.FakeHidBus` in tests."""

    transport = "hid"

    def __init__(self, source: str, hid_module: Any = None):
        from firmware_protocol.hid import HidapiTransport

        self.source = source
        if not source.startswith("hid:"):
            raise LinkError(f"{source}: HID sources look like hid:<path> or hid:VVVV:PPPP[:serial]")
        spec = source[4:]
        if hid_module is None:
            try:
                import hid as hid_module  # hidapi
            except ImportError as exc:
                raise LinkError(f"{source}: hidapi is not available ({exc})") from exc
        ids = _HID_IDS.match(spec)
        try:
            if ids:
                self._transport = HidapiTransport.open(int(ids[1], 16), int(ids[2], 16), ids[3],
                                                       device_factory=hid_module.device)
            else:
                self._transport = HidapiTransport.open(path=spec.encode(), device_factory=hid_module.device)
        except (OSError, ValueError) as exc:
            raise LinkError(f"{source}: cannot open ({exc})") from exc

    def read(self, max_bytes: int = 65536) -> bytes:
        try:
            return self._transport.read(HID_READ_TIMEOUT_MS)
        except (OSError, ValueError) as exc:
            raise LinkError(f"{self.source}: read failed ({exc})") from exc

    def write(self, data: bytes) -> None:
        try:
            self._transport.write(data)
        except (OSError, ValueError) as exc:
            raise LinkError(f"{self.source}: write failed ({exc})") from exc

    def close(self) -> None:
        try:
            self._transport.close()
        except (OSError, ValueError):
            pass


def open_link(source: str) -> Link:
    """The default link factory: ``hid:...`` sources over HID, everything else through pyserial."""
    return HidLink(source) if source.startswith("hid:") else SerialLink(source)


@dataclass(frozen=True)
class DiscoveredPort:
    source: str  # what to pass to open_link
    transport: str  # "serial" or "hid"
    serial_number: str | None
    description: str


def discover_serial(vid: int = STATION_VID, pid: int = STATION_PID) -> list[DiscoveredPort]:
    """USB serial ports whose VID:PID match (pyserial ``list_ports``)."""
    found = []
    for info in list_ports.comports():
        if info.vid == vid and info.pid == pid:
            found.append(DiscoveredPort(info.device, "serial", info.serial_number, info.description or ""))
    return found


def discover_hid(vid: int = STATION_VID, pid: int = STATION_PID,
                 enumerate_fn: Callable[[int, int], list[dict[str, Any]]] | None = None) -> list[DiscoveredPort]:
    """HID devices whose VID:PID match (``hid.enumerate`` from hidapi unless another enumerator is given)."""
    if enumerate_fn is None:
        try:
            import hid  # hidapi; optional at runtime on boards without libhidapi
        except ImportError:
            return []
        enumerate_fn = hid.enumerate
    found = []
    for info in enumerate_fn(vid, pid):
        path = info.get("path", b"")
        path = path.decode(errors="replace") if isinstance(path, bytes) else str(path)
        found.append(DiscoveredPort(f"hid:{path}", "hid", info.get("serial_number") or None,
                                    info.get("product_string") or ""))
    return found
