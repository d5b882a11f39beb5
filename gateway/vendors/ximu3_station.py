"""An x-IMU3 (x-io Technologies) as a gateway station, read through the vendor's `ximu3` library.

Source ``ximu3:<serial port>[?baud=115200]``. The library opens the port exactly as for the hardware, answers
to ``ping`` give the station name (``ximu3-<serial>``), and each decoded inertial message (microsecond device
time stamp, accelerometer in g, gyroscope in deg/s -> rad/s) goes through
`gateway.vendors.base.CallbackStationReader`, with the AHRS quaternion of the same time stamp (the device sends
it right after its inertial message at the factory rate divisor; its earth frame is NWU: Z up, north from a
magnetometer the engine does not rely on). An inertial message whose quaternion has not come when the next
inertial message does (quaternions off, or a lost message) is forwarded without one (NaN). One x-IMU3 is one
sensor (sensor 0). Its clock is real, so the alignment is as good as for the project's own stations."""
from __future__ import annotations

import math
import threading
from typing import Any
from urllib.parse import parse_qs

import numpy as np

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
        self._held: tuple[int, tuple, tuple] | None = None  # inertial sample waiting for its quaternion
        self._held_lock = threading.Lock()

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
        conn.add_inertial_callback(self._on_inertial)
        conn.add_quaternion_callback(self._on_quaternion)
        conn.add_receive_error_callback(self._on_receive_error)
        self._conn = conn

    def _on_inertial(self, m: Any) -> None:
        gyro_rps = tuple(math.radians(v) for v in (m.gyroscope_x, m.gyroscope_y, m.gyroscope_z))
        with self._held_lock:
            held, self._held = self._held, (m.timestamp, (m.accelerometer_x, m.accelerometer_y, m.accelerometer_z),
                                            gyro_rps)
        if held is not None:  # its quaternion never came
            self._on_sample(held[0], held[1], np.array(held[2]), np.full(4, np.nan))

    def _on_quaternion(self, m: Any) -> None:
        with self._held_lock:
            held = self._held
            if held is None or held[0] != m.timestamp:
                return
            self._held = None
        self._on_sample(held[0], held[1], np.array(held[2]), np.array([m.w, m.x, m.y, m.z]))

    def _on_receive_error(self, error: Any) -> None:
        self.receive_errors += 1

    def _disconnect(self) -> None:
        self._conn.close()
        self._conn = None
        self._held = None

    def _extra_status(self) -> dict[str, Any]:
        return {"device_name": self.device_name, "receive_errors": self.receive_errors}
