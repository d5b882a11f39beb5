"""Run as a script (under strace by tests/gateway/test_lsl_xdf.py): a gateway built from a court config with
``[lsl] enabled`` reads an emulated station and publishes through gateway.lsl.LslPublisher; a pylsl inlet in this
process resolves the outlet on loopback and records it. Prints JSON: what the gateway delivered and what the inlet
received."""
from __future__ import annotations

import json
import sys
import time

import numpy as np


def main(record_dir: str, seconds: float) -> None:
    from gateway.assembly import build_court
    from gateway.court_config import CourtConfig, LslConfig, StationsConfig

    config = CourtConfig(listen=("127.0.0.1", 0), record_dir=record_dir, name="lsltest", lsl=LslConfig(enabled=True),
                         stations=StationsConfig(urls=("emu://lsl1?sensors=3&rate=100&seed=2",)))
    delivered: list[tuple[str, int, list[float], list[list[float]]]] = []
    record = lambda b: delivered.append((b.station, b.sensor, list(b.t_host_s), b.acc_g.tolist()))  # noqa: E731
    with build_court(config) as court:
        publisher = court.gateway.sample_sinks[0].__self__  # the config's LslPublisher (loopback lsl_api.cfg)
        court.gateway.sample_sinks += (record,)
        import pylsl

        deadline = time.monotonic() + 10
        while not delivered and time.monotonic() < deadline:  # the station names itself in its HELLO
            time.sleep(0.01)
        station = delivered[0][0]
        found = pylsl.resolve_byprop("source_id", f"courtside/lsltest/{station}", 1, 10.0)
        inlet = pylsl.StreamInlet(found[0], max_buflen=60)
        inlet.open_stream(timeout=10.0)
        time.sleep(0.3)
        rows, stamps = [], []
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            chunk, ts = inlet.pull_chunk(timeout=0.2)
            rows += chunk
            stamps += ts
        info = inlet.info()
    print(json.dumps({"station": station, "delivered": delivered, "offset_s": publisher.clock.offset_s,
                      "rows": rows, "stamps": stamps, "name": info.name(), "type": info.type(),
                      "channels": info.channel_count(), "lslcfg": __import__("os").environ["LSLAPICFG"]}))


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]))
