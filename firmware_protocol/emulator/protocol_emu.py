"""pyserial URL handler: `serial.serial_for_url("emu://<name>?sensors=6&rate=100&loss=0.02&...")`.

Registered by `import firmware_protocol` (it appends this package to `serial.protocol_handler_packages`), so
production code that opens ports with `serial_for_url(config.port)` runs against an in-process station
unchanged. Query options: every name in `options.STATION_OPTIONS`, plus `clock=wall|manual` (default wall:
emulated time follows the wall clock, `speed` times faster; manual: only `port.link.advance(s)` moves time)
and `trace=<file.npy>&fps=<Hz>` for a recorded motion.

The station behind a name lives on in `STATIONS` after the port closes (a device stays powered while the
host closes and reopens its port): reopening `emu://<name>` reattaches to it and ignores the query.
`port.link.unplug()` makes reads/writes raise SerialException, as a real disconnect does.
"""
from __future__ import annotations

import time
from urllib.parse import urlsplit

from serial.serialutil import PortNotOpenError, SerialBase, SerialException, to_bytes

from .link import EmulatorLink
from .motion import TraceSource
from .options import apply_options, parse_query
from .station import BaseStation, StationConfig

STATIONS: dict[str, EmulatorLink] = {}
_POLL_S = 0.001


def link_from_url(url: str) -> EmulatorLink:
    """The station behind an emu:// URL, created from its query on first use."""
    parts = urlsplit(url)
    if parts.scheme != "emu" or not parts.netloc:
        raise SerialException(f"expected emu://<name>?option=value..., got {url!r}")
    name = parts.netloc
    if name in STATIONS:
        return STATIONS[name]
    options = parse_query(parts.query)
    clock = options.pop("clock", "wall")
    speed = float(options.pop("speed", "1"))
    trace = options.pop("trace", None)
    fps = float(options.pop("fps", "100"))
    if clock not in {"wall", "manual"}:
        raise SerialException(f"{url}: clock must be 'wall' or 'manual', got {clock!r}")
    try:
        config = apply_options(StationConfig(), options)
        motion = TraceSource.from_npy(trace, fps) if trace else None
        link = EmulatorLink(BaseStation(config, motion), realtime=clock == "wall", speed=speed)
    except ValueError as exc:
        raise SerialException(f"{url}: {exc}") from None
    STATIONS[name] = link
    return link


class Serial(SerialBase):
    """A pyserial port whose other end is an emulated base station (no thread; time catches up on read)."""

    def __init__(self, *args, **kwargs) -> None:
        self.link: EmulatorLink | None = None
        self._rx = bytearray()
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self.is_open:
            raise SerialException("port is already open")
        if self._port is None:
            raise SerialException("port must be configured before it can be used")
        link = link_from_url(self.portstr)
        if not link.station.plugged:
            raise SerialException(f"could not open port {self.portstr}: device unplugged")
        self.link = link
        self._rx = bytearray()
        self.is_open = True

    def close(self) -> None:
        self.is_open = False
        super().close()

    def _reconfigure_port(self) -> None:
        """Baud rate, parity etc. mean nothing on a USB CDC link; accepted and ignored."""

    def _check(self) -> EmulatorLink:
        if not self.is_open or self.link is None:
            raise PortNotOpenError()
        if not self.link.station.plugged:
            raise SerialException("device disconnected (emulated unplug)")
        return self.link

    def _fill(self) -> bool:
        """Move the station's output into the receive buffer; False once unplugged. Bytes already taken stay
        readable after an unplug (the ground truth counts them as delivered); then reads raise."""
        if not self.is_open or self.link is None:
            raise PortNotOpenError()
        if self.link.station.plugged:
            self._rx += self.link.take()
            return True
        if not self._rx:
            raise SerialException("device disconnected (emulated unplug)")
        return False

    @property
    def in_waiting(self) -> int:
        self._fill()
        return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        deadline = None if self._timeout is None else time.monotonic() + self._timeout
        while self._fill() and len(self._rx) < size and self._timeout != 0:
            if deadline is not None and time.monotonic() >= deadline:
                break
            time.sleep(_POLL_S)
        data = bytes(self._rx[:size])
        del self._rx[:size]
        return data

    def write(self, data: bytes) -> int:
        data = to_bytes(data)
        self._check().write(data)
        return len(data)

    def reset_input_buffer(self) -> None:
        self._rx = bytearray()
        self._check().take()

    def reset_output_buffer(self) -> None:
        """Writes reach the station immediately; nothing to discard."""

    @property
    def out_waiting(self) -> int:
        return 0

    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True
