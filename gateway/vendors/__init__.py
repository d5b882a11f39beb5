"""IMUs people can buy, as gateway stations beside the project's own base stations (docs/imu-import.md).

A station source with a vendor prefix is read through the vendor's own library instead of the project's
protocol decoder: ``ximu3:/dev/ttyACM0`` (x-io x-IMU3, `ximu3`), ``shimmer:/dev/rfcomm0`` (Shimmer3, `pyshimmer`). Each reader turns device time stamps into the
gateway clock with the same lower-envelope estimator and delivers the same `SampleBlock`s, so recording,
streaming, statistics and LSL work unchanged."""
from __future__ import annotations

from typing import Any

VENDOR_PREFIXES = ("ximu3:", "shimmer:")
_SHARED_OPTIONS = ("reconnect_interval_s", "clock_window_s", "lock_after_s")


def make_reader(source: str, sink: Any, **options: Any) -> Any:
    """The reader for ``source``: a vendor reader for a vendor prefix, else the project's `StationReader`."""
    shared = {k: v for k, v in options.items() if k in _SHARED_OPTIONS}
    if source.startswith("ximu3:"):
        from gateway.vendors.ximu3_station import Ximu3Reader

        return Ximu3Reader(source, sink, **shared)
    if source.startswith("shimmer:"):
        from gateway.vendors.shimmer_station import ShimmerReader

        return ShimmerReader(source, sink, **shared)
    from gateway.station import StationReader

    return StationReader(source, sink, **options)
