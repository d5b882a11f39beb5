"""Emulated USB HID for tests: `FakeHidBus` / `FakeHidDevice` stand in for the cython-hidapi `hid` module over
emulated stations (UHID is unavailable in the sandbox and in CI). The report framing both sides use is defined
once in `firmware_protocol.hid`, which the gateway's real HID path imports without this module."""
from __future__ import annotations

import time
from typing import Any

from ..hid import (DEFAULT_PRODUCT_ID, DEFAULT_VENDOR_ID, IN_REPORT_ID, OUT_REPORT_ID, REPORT_PAYLOAD_BYTES,
                   pack_reports, unpack_report)
from .link import EmulatorLink


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
