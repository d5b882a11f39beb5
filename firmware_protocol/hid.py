"""USB HID report framing, defined once: the same frame byte stream carried in 64-byte reports (PROTOCOL.md
section 3), and the host-side transport over a hidapi device that the gateway's real HID links use.

    byte 0   report id: 0x01 station->host (IN), 0x02 host->station (OUT)
    byte 1   n, stream bytes in this report (0..62)
    2..63    n stream bytes, zero padded

`HidapiTransport` adapts anything with the cython-hidapi `hid.device()` API; for real hardware it wraps
`hid.device()` (the `hidapi` package, imported lazily). The emulator's `FakeHidBus` / `FakeHidDevice`
(`firmware_protocol.emulator.hid_transport`) expose that same API over an emulated station (UHID is unavailable
in the sandbox and in CI) and use this module's framing on the device side, so the adapter code that talks to
real devices is the code the tests exercise, and the real path never imports the emulator. Quirks kept from
hidapi: `read` returns [] on timeout, a write must start with the report id, a removed device makes read/write
raise OSError.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

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
