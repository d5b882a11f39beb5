"""IMUs people can buy, as gateway stations beside the project's own base stations (docs/imu-import.md).

A station source with a vendor prefix is read through the vendor's own library instead of the project's
protocol decoder: ``ximu3:/dev/ttyACM0`` (x-io x-IMU3, `ximu3`), ``shimmer:/dev/rfcomm0`` (Shimmer3, `pyshimmer`). Each reader turns device time stamps into the
gateway clock with the same lower-envelope estimator and delivers the same `SampleBlock`s, so recording,
streaming, statistics and LSL work unchanged."""
from __future__ import annotations

import importlib
from typing import Any

# source prefix -> (module, reader class); imported only when a source names it (the vendor libraries are optional)
READERS = {
    "ximu3:": ("gateway.vendors.ximu3_station", "Ximu3Reader"),
    "shimmer:": ("gateway.vendors.shimmer_station", "ShimmerReader"),
}
_SHARED_OPTIONS = ("reconnect_interval_s", "clock_window_s", "lock_after_s")


def make_reader(source: str, sink: Any, **options: Any) -> Any:
    """The reader for ``source``: the `READERS` entry of its prefix, else the project's `StationReader`."""
    for prefix, (module, name) in READERS.items():
        if source.startswith(prefix):
            shared = {k: v for k, v in options.items() if k in _SHARED_OPTIONS}
            return getattr(importlib.import_module(module), name)(source, sink, **shared)
    from gateway.station import StationReader

    return StationReader(source, sink, **options)
