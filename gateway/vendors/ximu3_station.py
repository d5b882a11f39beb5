"""An x-IMU3 (x-io Technologies) as a gateway station, read through the vendor's `ximu3` library.

Source ``ximu3:<serial port>[?baud=115200]``. The library opens the port exactly as for the hardware, answers
to ``ping`` give the station name (``ximu3-<serial>``), and each decoded inertial message (microsecond device
time stamp, accelerometer in g) goes through `gateway.vendors.base.CallbackStationReader`. One x-IMU3 is one
sensor (sensor 0). Its clock is real, so the alignment is as good as for the project's own stations."""
from __future__ import annotations

from typing import Any
from urllib.parse import parse_qs

from gateway.links import LinkError
from gateway.vendors.base import CallbackStationReader


class Ximu3Reader(CallbackStationReader):
    device = "x-IMU3"

    def __init__(self, source: str, sink: Any, **options: Any) -> None:
        super().__init__(source, sink, 1e6, **options)
        path, _, query = source[len("ximu3:"):].partition("?")
        self.path, self.baud = path, int(parse_qs(query).get("baud", ["115200"])[0])
        self.device_name: str | None = None
        self.receive_errors = 0
        self._conn: Any = None

    def _connect(self) -> None:
        import ximu3

        conn = ximu3.Connection(ximu3.SerialConnectionConfig(self.path, self.baud, False))
        try:
            conn.open()
        except RuntimeError as exc:  # the library's "Unable to open Serial ...: <reason>"
            raise LinkError(str(exc)) from None
        ping = conn.ping()
        if ping is None or not ping.serial_number:  # None: no answer within the library's timeout
            conn.close()
            raise LinkError(f"{self.path}: no answer to ping (not an x-IMU3?)")
        self.device_name, self.identity = ping.device_name, ping.serial_number
        conn.add_inertial_callback(lambda m: self._on_sample(
            m.timestamp, (m.accelerometer_x, m.accelerometer_y, m.accelerometer_z)))
        conn.add_receive_error_callback(self._on_receive_error)
        self._conn = conn

    def _on_receive_error(self, error: Any) -> None:
        self.receive_errors += 1

    def _disconnect(self) -> None:
        self._conn.close()
        self._conn = None

    def _extra_status(self) -> dict[str, Any]:
        return {"device_name": self.device_name, "receive_errors": self.receive_errors}
