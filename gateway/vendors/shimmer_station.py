"""A Shimmer3 as a gateway station, read through the vendor's `pyshimmer` (LogAndStream firmware over Bluetooth
serial: the rfcomm port, e.g. ``shimmer:/dev/rfcomm0``).

On connect: a firmware-version probe of our own (pyshimmer has no timeouts), then pyshimmer's initialize, device name (the station is ``shimmer3-<name>``), the
device's own calibration of the wide-range accelerometer (offset, sensitivity in LSB per m/s², alignment), the
sampling rate in ticks of its 32768 Hz clock (so the nominal period is exact), then streaming. Each data packet
carries the 24-bit device time stamp, unwrapped here (it wraps every 512 s), and the raw accelerometer, calibrated
as Shimmer documents: ``a = R⁻¹ (raw − offset) / sensitivity``; when the gyroscope is enabled too, its angular
rate, calibrated alike with the sensitivity stored x100 (LSB per deg/s), is forwarded in rad/s. (Shimmer3 streams
no orientation: its quaternion is computed on the PC by Shimmer's own software.)"""
from __future__ import annotations

import contextlib
import io
from typing import Any

import numpy as np

from gateway.links import LinkError
from gateway.vendors.base import CallbackStationReader

WRAP_TICKS = 1 << 24
PROBE_TIMEOUT_S = 1.0
ACK, GET_FW_VERSION, FW_VERSION_RESPONSE, FW_VERSION_BYTES = 0xFF, 0x2E, 0x2F, 6
WIDE_RANGE_ACCEL = 3  # index of the wide-range accelerometer in Shimmer's all-calibration record
GYRO = 1  # index of the gyroscope in that record
GRAVITY_MPS2 = 9.80665


class ShimmerReader(CallbackStationReader):
    device = "Shimmer3"

    def __init__(self, source: str, sink: Any, **options: Any) -> None:
        super().__init__(source, sink, 32768.0, **options)
        self.path = source[len("shimmer:"):]
        self.firmware: str | None = None
        self._shimmer: Any = None
        self._serial: Any = None
        self._last24: int | None = None
        self._wraps = 0
        self._channels: tuple = ()
        self._offset = self._gain = None
        self._gyro_channels: tuple = ()
        self._gyro_offset = self._gyro_gain = None

    def _connect(self) -> None:
        import serial
        from pyshimmer import ShimmerBluetooth
        from pyshimmer.dev.channels import EChannelType

        try:
            self._serial = serial.Serial(self.path, 115200, timeout=PROBE_TIMEOUT_S)
        except serial.SerialException as exc:
            raise LinkError(f"cannot open {self.path}: {exc}") from None
        self._probe()
        shimmer = ShimmerBluetooth(self._serial)
        try:
            shimmer.initialize()
            self.identity = shimmer.get_device_name()
            calibration = shimmer.get_all_calibration()
            self.period_ticks = float(round(self.tick_hz / shimmer.get_sampling_rate()))
            channels = shimmer.get_data_types()
        except Exception as exc:  # pyshimmer raises plain RuntimeError/ValueError on protocol trouble
            self._shutdown(shimmer)
            raise LinkError(f"{self.path}: not a Shimmer answering its protocol ({exc})") from None
        self._channels = (EChannelType.ACCEL_LSM303DLHC_X, EChannelType.ACCEL_LSM303DLHC_Y,
                          EChannelType.ACCEL_LSM303DLHC_Z)
        if not all(c in channels for c in self._channels):
            self._shutdown(shimmer)
            raise LinkError(f"{self.path}: the wide-range accelerometer is not enabled on this Shimmer")
        self._offset = np.array(calibration.get_offset_bias(WIDE_RANGE_ACCEL), float)
        sensitivity = np.array(calibration.get_sensitivity(WIDE_RANGE_ACCEL), float)
        alignment = np.array(calibration.get_ali_mat(WIDE_RANGE_ACCEL), float).reshape(3, 3) / 100.0
        self._gain = np.linalg.inv(alignment) / sensitivity[None, :] / GRAVITY_MPS2  # raw - offset -> g
        gyro = (EChannelType.GYRO_MPU9150_X, EChannelType.GYRO_MPU9150_Y, EChannelType.GYRO_MPU9150_Z)
        self._gyro_channels = gyro if all(c in channels for c in gyro) else ()
        if self._gyro_channels:
            self._gyro_offset = np.array(calibration.get_offset_bias(GYRO), float)
            gyro_sensitivity = np.array(calibration.get_sensitivity(GYRO), float) / 100.0  # LSB per deg/s
            gyro_alignment = np.array(calibration.get_ali_mat(GYRO), float).reshape(3, 3) / 100.0
            self._gyro_gain = np.linalg.inv(gyro_alignment) / gyro_sensitivity[None, :] * (np.pi / 180.0)
        self._last24, self._wraps = None, 0
        shimmer.add_stream_callback(self._on_packet)
        shimmer.start_streaming()
        self._shimmer = shimmer

    def _probe(self) -> None:
        """Ask for the firmware version ourselves first: pyshimmer waits without a timeout, so a port with some
        other device on it would hang its initialisation forever."""
        self._serial.reset_input_buffer()
        self._serial.write(bytes([GET_FW_VERSION]))
        answer = self._serial.read(2 + FW_VERSION_BYTES)
        if answer[:2] != bytes([ACK, FW_VERSION_RESPONSE]):
            self._serial.close()
            raise LinkError(f"{self.path}: not a Shimmer answering its protocol (firmware version request "
                            f"got {answer[:8].hex() or 'nothing'})")
        self._serial.timeout = None  # pyshimmer's read loop blocks; it is ended by cancel_read

    def _on_packet(self, packet: Any) -> None:
        from pyshimmer.dev.channels import EChannelType

        stamp = int(packet[EChannelType.TIMESTAMP])
        if self._last24 is not None and stamp < self._last24 - WRAP_TICKS // 2:
            self._wraps += 1
        self._last24 = stamp
        raw = np.array([packet[c] for c in self._channels], float)
        gyro = None
        if self._gyro_channels:
            gyro = self._gyro_gain @ (np.array([packet[c] for c in self._gyro_channels], float) - self._gyro_offset)
        self._on_sample(stamp + self._wraps * WRAP_TICKS, self._gain @ (raw - self._offset), gyro)

    def _shutdown(self, shimmer: Any) -> None:
        with contextlib.redirect_stdout(io.StringIO()):  # pyshimmer prints when its read loop ends
            shimmer.shutdown()

    def _disconnect(self) -> None:
        try:
            self._shimmer.stop_streaming()
        except Exception:  # the link may already be gone; shutting down is all that is left
            pass
        self._shutdown(self._shimmer)
        self._shimmer = None
