"""Run as a script (under strace by tests/gateway/test_lsl_xdf.py): a gateway built from a court config with
``[lsl] enabled`` reads an emulated station (protocol v2: orientation + angular rate too) and publishes through
gateway.lsl.LslPublisher; pylsl inlets in this process resolve its two outlets (accelerations, orientation) on
loopback and record them. Prints JSON: what the gateway delivered and what the inlets received."""
from __future__ import annotations

import json
import sys
import time

import numpy as np


def main(record_dir: str, seconds: float) -> None:
    from gateway.assembly import build_court
    from gateway.court_config import CourtConfig, LslConfig, StationsConfig

    config = CourtConfig(listen=("127.0.0.1", 0), record_dir=record_dir, name="lsltest", lsl=LslConfig(enabled=True),
                         stations=StationsConfig(urls=("emu://lsl1?sensors=3&rate=100&seed=2&orientation=1",)))
    delivered: list[tuple[str, int, list[float], list[list[float]]]] = []
    record = lambda b: delivered.append((b.station, b.sensor, list(b.t_host_s), b.acc_g.tolist(),  # noqa: E731
                                         np.c_[b.quat_wxyz, b.gyro_rps].tolist()))
    with build_court(config) as court:
        publisher = court.gateway.sample_sinks[0].__self__  # the config's LslPublisher (loopback lsl_api.cfg)
        court.gateway.sample_sinks += (record,)
        import pylsl

        deadline = time.monotonic() + 10
        while not delivered and time.monotonic() < deadline:  # the station names itself in its HELLO
            time.sleep(0.01)
        station = delivered[0][0]
        inlets = []
        for source_id in (f"courtside/lsltest/{station}", f"courtside/lsltest/{station}/orientation"):
            found = pylsl.resolve_byprop("source_id", source_id, 1, 10.0)
            inlets.append(pylsl.StreamInlet(found[0], max_buflen=60))
            inlets[-1].open_stream(timeout=10.0)
        time.sleep(0.3)
        (rows, stamps), (ori_rows, ori_stamps) = ([], []), ([], [])
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            for inlet, (r, s) in zip(inlets, ((rows, stamps), (ori_rows, ori_stamps))):
                chunk, ts = inlet.pull_chunk(timeout=0.1)
                r += chunk
                s += ts
        info, ori_info = (inlet.info() for inlet in inlets)
    print(json.dumps({"station": station, "delivered": delivered, "offset_s": publisher.clock.offset_s,
                      "rows": rows, "stamps": stamps, "name": info.name(), "type": info.type(),
                      "channels": info.channel_count(), "lslcfg": __import__("os").environ["LSLAPICFG"],
                      "ori_rows": ori_rows, "ori_stamps": ori_stamps, "ori_name": ori_info.name(),
                      "ori_type": ori_info.type(), "ori_channels": ori_info.channel_count()}))


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]))
