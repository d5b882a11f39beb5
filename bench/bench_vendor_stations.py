"""Vendor stations (x-IMU3 via ximu3 in binary and ASCII mode, Shimmer3 via pyshimmer) through a real Gateway
against their pty emulators:
clock alignment of the recorded samples against the emulators' true latch times (online estimate and the
offline re-fit), the loss counted in the take vs the emulator's drops in the same span, and the CPU cost.

    python bench/bench_vendor_stations.py [--seconds 20] [--ximu3-rate 400]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from gateway.daemon import Gateway  # noqa: E402
from gateway.recorder import load_take, realign_take  # noqa: E402
from firmware_protocol.emulator.shimmer_device import ShimmerEmulator  # noqa: E402
from firmware_protocol.emulator.ximu3_device import Ximu3Emulator  # noqa: E402


def run(emu, source: str, seconds: float) -> dict:
    with tempfile.TemporaryDirectory() as tmp, emu, Gateway([source], listen=("127.0.0.1", 0), record_dir=tmp) as gw:
        deadline = time.monotonic() + 10
        while gw.list_stations()[0]["station"] == source and time.monotonic() < deadline:
            time.sleep(0.05)
        station = gw.list_stations()[0]["station"]
        gw.recorder.start("b")
        cpu0 = time.process_time()
        time.sleep(seconds)
        cpu = time.process_time() - cpu0
        gw.recorder.stop()
        take = load_take(Path(tmp) / "b")
    ticks = np.array(getattr(emu.truth, "device_us", None) or emu.truth.ticks)
    index = {int(t) % (1 << 32): k for k, t in enumerate(ticks)}
    cols = take.samples[(station, 0)]
    host = np.array(emu.truth.host_s)[[index[int(r)] for r in cols["raw_ticks"]]]
    settled = host > host[0] + 2.0
    online = np.abs(cols["t_host_s"] - host)[settled] * 1e3
    offline = np.abs(realign_take(take)[(station, 0)] - host) * 1e3
    # loss within the take: counted from the gateway's rebuilt counters, and true (the emulator's drops between
    # the take's first and last sample; drops before the first received sample show in no gap)
    counter = cols["counter"].astype(np.int64)
    counted = int((np.diff(counter) - 1).sum())
    sent = ticks[[index[int(r)] for r in cols["raw_ticks"]]]
    dropped = np.array(getattr(emu.truth, "dropped_us", []))
    true = int(((dropped > sent.min()) & (dropped < sent.max())).sum()) if dropped.size else 0
    return {"station": station, "samples": len(host), "lost": counted, "dropped": true, "online": online,
            "offline": offline, "cpu": cpu / seconds}


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--ximu3-rate", type=float, default=100.0, help="x-IMU3 inertial message rate, Hz")
    args = p.parse_args()
    burst = max(4, int(args.ximu3_rate / 25))  # USB-like: a burst every ~40 ms
    xb = Ximu3Emulator(rate_hz=args.ximu3_rate, drift_ppm=80.0, loss=0.02, seed=1, mode="binary", burst=burst)
    xa = Ximu3Emulator(rate_hz=args.ximu3_rate, drift_ppm=80.0, loss=0.02, seed=1, mode="ascii", burst=burst)
    s = ShimmerEmulator(rate_hz=102.4, drift_ppm=-30.0, seed=2)
    print(f"{'station':24s} {'samples':>8s} {'lost (true)':>12s} {'online p50/p99/max ms':>24s} "
          f"{'offline p50/p99/max ms':>24s} {'CPU %':>6s}")
    for emu, source, label in ((xb, f"ximu3:{xb.path}", " (binary)"), (xa, f"ximu3:{xa.path}", " (ASCII)"),
                               (s, f"shimmer:{s.path}", "")):
        r = run(emu, source, args.seconds)
        on, off = (f"{np.percentile(a, 50):.3f}/{np.percentile(a, 99):.3f}/{a.max():.3f}" for a in (r["online"], r["offline"]))
        print(f"{r['station'] + label:24s} {r['samples']:8d} {r['lost']:5d} ({r['dropped']:4d}) {on:>24s} {off:>24s} "
              f"{100 * r['cpu']:6.1f}")


if __name__ == "__main__":
    main()
