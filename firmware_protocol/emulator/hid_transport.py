"""USB HID transport: the same frame byte stream carried in 64-byte reports (layout in PROTOCOL.md section 3).

    byte 0   report id: 0x01 station->host (IN), 0x02 host->station (OUT)
    byte 1   n, stream bytes in this report (0..62)
    2..63    n stream bytes, zero padded

`HidapiTransport` adapts anything with the cython-hidapi `hid.device()` API; for real hardware it wraps
`hid.device()` (the `hidapi` package, imported lazily). The in-process `FakeHidBus` / `FakeHidDevice` expose
that same API over an emulated station (UHID is unavailable in the sandbox and in CI), so the adapter code
that talks to real devices is the code the tests exercise. Quirks kept from hidapi: `read` returns [] on
timeout, a write must start with the report id, a removed device makes read/write raise OSError.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, Protocol

from .link import EmulatorLink

REPORT_BYTES = 64
REPORT_PAYLOAD_BYTES = 62
IN_REPORT_ID = 0x01
OUT_REPORT_ID = 0x02
DEFAULT_VENDOR_ID = 0x1209        # pid.codes open-source vendor id
DEFAULT_PRODUCT_ID = 0xC0DE


def pack_reports(data: bytes, report_id: int) -> list[bytes]:
    """Split stream bytes into 64-byte reports."""
    reports = []
    for i in range(0, len(data), REPORT_PAYLOAD_BYTES):
        chunk = data[i:i + REPORT_PAYLOAD_BYTES]
        reports.append(bytes([report_id, len(chunk)]) + chunk + bytes(REPORT_PAYLOAD_BYTES - len(chunk)))
    return reports


def unpack_report(report: bytes | list[int], report_id: int) -> bytes:
    """Stream bytes carried by one report; ValueError if it is not one of ours."""
    report = bytes(report)
    if len(report) < 2 or report[0] != report_id:
        raise ValueError(f"not a report with id {report_id:#04x}: {report[:4].hex()}")
    n = report[1]
    if n > REPORT_PAYLOAD_BYTES or len(report) < 2 + n:
        raise ValueError(f"report claims {n} bytes but holds {len(report) - 2}")
    return report[2:2 + n]


class HidTransport(Protocol):
    def read(self, timeout_ms: int) -> bytes: ...
    def write(self, data: bytes) -> None: ...
    def close(self) -> None: ...


class HidapiTransport:
    """Host side: frame stream over a hidapi device. Bad reports are counted and skipped, never raised."""

    def __init__(self, device: Any) -> None:
        self._device = device
        self.bad_reports = 0

    @classmethod
    def open(cls, vendor_id: int = DEFAULT_VENDOR_ID, product_id: int = DEFAULT_PRODUCT_ID,
             serial_number: str | None = None, path: bytes | None = None,
             device_factory: Callable[[], Any] | None = None) -> HidapiTransport:
        """Open a real device (default factory `hid.device`) or any object with the same API."""
        if device_factory is None:
            import hid  # the `hidapi` package; lazy so that hosts without libusb/hidraw can still import us

            device_factory = hid.device
        device = device_factory()
        if path is not None:
            device.open_path(path)
        else:
            device.open(vendor_id, product_id, serial_number)
        return cls(device)

    def read(self, timeout_ms: int) -> bytes:
        report = self._device.read(REPORT_BYTES, timeout_ms)
        if not report:
            return b""
        try:
            return unpack_report(report, IN_REPORT_ID)
        except ValueError:
            self.bad_reports += 1
            return b""

    def write(self, data: bytes) -> None:
        for report in pack_reports(data, OUT_REPORT_ID):
            if self._device.write(report) < 0:
                raise OSError("HID write failed")

    def close(self) -> None:
        self._device.close()


class FakeHidBus:
    """Stands in for the `hid` module: `enumerate()` and `device()` over registered emulated stations."""

    def __init__(self) -> None:
        self._devices: dict[bytes, tuple[EmulatorLink, dict[str, Any]]] = {}

    def attach(self, link: EmulatorLink, vendor_id: int = DEFAULT_VENDOR_ID, product_id: int = DEFAULT_PRODUCT_ID,
               serial_number: str | None = None) -> bytes:
        """Plug a station in; returns its device path."""
        path = f"emu-hid-{len(self._devices)}".encode()
        info = {
            "path": path, "vendor_id": vendor_id, "product_id": product_id,
            "serial_number": serial_number or f"{link.station.config.serial:08X}", "release_number": 0x0100,
            "manufacturer_string": "Courtside", "product_string": "Courtside emulated base station",
            "usage_page": 0xFF00, "usage": 1, "interface_number": 0,
        }
        self._devices[path] = (link, info)
        return path

    def enumerate(self, vendor_id: int = 0, product_id: int = 0) -> list[dict[str, Any]]:
        return [dict(info) for link, info in self._devices.values()
                if link.station.plugged and vendor_id in (0, info["vendor_id"])
                and product_id in (0, info["product_id"])]

    def device(self) -> FakeHidDevice:
        return FakeHidDevice(self)

    def _find(self, path: bytes | None, vendor_id: int, product_id: int,
              serial_number: str | None) -> tuple[EmulatorLink, dict[str, Any]]:
        for p, (link, info) in self._devices.items():
            if not link.station.plugged:
                continue
            if path is not None and p == path:
                return link, info
            if path is None and (info["vendor_id"], info["product_id"]) == (vendor_id, product_id) \
                    and serial_number in (None, info["serial_number"]):
                return link, info
        raise OSError("open failed")


class FakeHidDevice:
    """The cython-hidapi `hid.device` API, backed by an emulated station (device side of the reports)."""

    def __init__(self, bus: FakeHidBus) -> None:
        self._bus = bus
        self._link: EmulatorLink | None = None
        self._info: dict[str, Any] = {}
        self._nonblocking = False

    def open(self, vendor_id: int = 0, product_id: int = 0, serial_number: str | None = None) -> None:
        self._link, self._info = self._bus._find(None, vendor_id, product_id, serial_number)

    def open_path(self, path: bytes) -> None:
        self._link, self._info = self._bus._find(path, 0, 0, None)

    def close(self) -> None:
        self._link = None

    def set_nonblocking(self, flag: int | bool) -> int:
        self._nonblocking = bool(flag)
        return 0

    def _live(self) -> EmulatorLink:
        if self._link is None:
            raise ValueError("not open")
        if not self._link.station.plugged:
            raise OSError("read error (device removed)")
        return self._link

    def read(self, max_length: int, timeout_ms: int = 0) -> list[int]:
        link = self._live()
        if self._nonblocking:
            deadline: float | None = time.monotonic()
        else:  # as cython-hidapi: timeout 0 in blocking mode means hid_read, which waits for a report
            deadline = time.monotonic() + timeout_ms / 1000 if timeout_ms > 0 else None
        while True:
            data = link.take(REPORT_PAYLOAD_BYTES)
            if data:
                return list(pack_reports(data, IN_REPORT_ID)[0][:max_length])
            if deadline is not None and time.monotonic() >= deadline:
                return []
            time.sleep(0.001)
            link = self._live()

    def write(self, data: bytes | list[int]) -> int:
        link = self._live()
        try:
            link.write(unpack_report(bytes(data), OUT_REPORT_ID))
        except ValueError:
            return -1
        return len(data)

    def get_manufacturer_string(self) -> str:
        return self._info.get("manufacturer_string", "")

    def get_product_string(self) -> str:
        return self._info.get("product_string", "")

    def get_serial_number_string(self) -> str:
        return self._info.get("serial_number", "")
