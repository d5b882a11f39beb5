"""Run as a script (under strace -f by tests/gateway/test_lsl_xdf.py): what a user does with LSL — `courtside
gateway --config court.toml` (``[lsl] enabled``, an x-IMU3 in binary mode emulated here on a pty, read by the
vendor's library) as its own process, and an LSL inlet in this process (a recorder such as LabRecorder, with the
same loopback ``lsl_api.cfg``) that resolves the gateway's outlet and records it. Prints JSON: what the device
sent (true latch times, accelerations) and what the inlet received."""
from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np


def main(workdir: str, seconds: float) -> None:
    from gateway.lsl import use_loopback_config
    from firmware_protocol.emulator.ximu3_device import Ximu3Emulator

    cfg = use_loopback_config(workdir)  # before pylsl loads liblsl, as the gateway does
    import pylsl

    work = Path(workdir)
    still = [0.0, 0.0, 1.0] + np.random.default_rng(4).normal(0.0, 0.005, (12000, 3))  # 2 min: no repeats
    # LSL at machine scope sees every outlet on this machine: a serial of this run's own keeps the source id apart
    # from any other run's
    serial = f"{zlib.crc32(str(work.resolve()).encode()) & 0xFFFFFFFF:08X}"
    with Ximu3Emulator(serial=serial, rate_hz=100.0, drift_ppm=60.0, acc_g=still) as device:
        (work / "court.toml").write_text(f"""
name = "lslx"
listen = "127.0.0.1:0"
record_dir = "takes"
log_level = "warning"
status_interval_s = 60

[stations]
ports = ["ximu3:{device.path}"]

[lsl]
enabled = true
""")
        gateway = subprocess.Popen([sys.executable, "-m", "gateway.cli", "gateway", "--config", "court.toml"],
                                   cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            while "gateway listening" not in (line := gateway.stdout.readline()):  # its SIGTERM handler is set
                if not line:
                    raise SystemExit(f"gateway exited early: {gateway.wait()} {gateway.stderr.read()[-2000:]}")
            found = pylsl.resolve_byprop("source_id", f"courtside/lslx/ximu3-{serial}", 1, 60.0)
            if not found:
                raise SystemExit("no outlet resolved within 60 s")
            inlet = pylsl.StreamInlet(found[0], max_buflen=60)
            inlet.open_stream(timeout=10.0)
            rows, stamps = [], []
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                chunk, ts = inlet.pull_chunk(timeout=0.2)
                rows += chunk
                stamps += ts
            info = inlet.info()
            inlet.close_stream()  # before the outlet goes: no reconnect attempts left running
            del inlet
        finally:
            gateway.send_signal(signal.SIGTERM)
            _, err = gateway.communicate(timeout=30)
        sent = {"host_s": list(device.truth.host_s), "acc_g": [a.tolist() for a in device.truth.acc_g]}
    print(json.dumps({"rows": rows, "stamps": stamps, "sent": sent, "name": info.name(), "serial": serial,
                      "lslcfg": str(cfg),
                      "local_minus_monotonic_s": pylsl.local_clock() - time.monotonic(),
                      "gateway_exit": gateway.returncode, "gateway_stderr": err[-2000:]}))


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]))
