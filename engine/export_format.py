"""The gateway's export .npz (`courtside gateway export --npz`), defined once: `gateway.recorder.export_npz`
writes these keys and `engine.graph.inputs` reads them back.

Per recorded sensor, ``<station>/<sensor>/<column>``: the recorded sample columns (``acc_g`` (N, 3) g,
``t_host_s`` (N,) s, ...) and ``t_realigned_s`` (N,) s, the offline clock re-fit; ``meta`` and ``messages`` are JSON
strings (the recording's header, every non-sample message). Adding a per-sensor channel is one name in
`OPTIONAL_CHANNELS`; the key helpers below are the only place the layout is spelled."""
from __future__ import annotations

from collections.abc import Iterable

ACC_G, QUAT_WXYZ, GYRO_RPS = "acc_g", "quat_wxyz", "gyro_rps"
T_HOST_S, T_REALIGNED_S = "t_host_s", "t_realigned_s"
TIME_COLUMNS = (T_HOST_S, T_REALIGNED_S)  # online sample times, or re-fitted offline
OPTIONAL_CHANNELS = (QUAT_WXYZ, GYRO_RPS)  # from sensors that stream them: (N, 4) sensor -> device earth, (N, 3) rad/s
SAMPLE_CHANNELS = (ACC_G, *OPTIONAL_CHANNELS)  # per-sensor readings a take reader may use (acc_g is required)
META, MESSAGES = "meta", "messages"


def sensor_key(sensor: str, column: str) -> str:
    """The key of one recorded sensor's column; ``sensor`` is ``"<station>/<sensor>"`` (`sensor_name`)."""
    return f"{sensor}/{column}"


def sensor_name(station: str, sensor: int | str) -> str:
    """``"<station>/<sensor>"``: how a recorded sensor is named in the export (and in --sensor-map)."""
    return f"{station}/{sensor}"


def recorded_sensors(keys: Iterable[str], column: str = ACC_G) -> list[str]:
    """The recorded sensors (``"<station>/<sensor>"``, sorted) that have ``column`` in an export's keys."""
    suffix = "/" + column
    return sorted({k[: -len(suffix)] for k in keys if k.endswith(suffix)})
