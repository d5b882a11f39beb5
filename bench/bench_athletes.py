"""Two athletes on the court's board: `courtside gateway --config court.toml` with 2 athletes x 6 sensors x 100 Hz
plus the overhead camera (one track each), measured from outside: resident memory and CPU share of the gateway
process (issue 20: <= 100 MB RSS, <= 25 % of a core).

    nice -n 10 .venv/bin/python bench/bench_athletes.py [--seconds 60]

The emulated stations run in a separate process (on a court they are USB devices, not the gateway's work); the
camera is a rendered court video with both players (`courtside camera synth --opponent`, 640x360, 30 fps, looped)
read paced like a live camera. Baseline in the same run: the same gateway and stations with one athlete and no
camera, so the camera's and the second athlete's cost read as a difference on any machine.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

STATIONS_SCRIPT = """
import json, sys, time
from gateway.assembly import start_athlete_stations
from gateway.court_config import load_court_config
stations = start_athlete_stations(load_court_config(sys.argv[1]))
print(json.dumps([s.path for s in stations]), flush=True)
sys.stdin.read()
for s in stations:
    s.stop()
"""

ATHLETES = """
[[athletes]]
name = "alice"
side = "near"
sensors = [{alice}]
clips = ["16_32"]
[[athletes]]
name = "bob"
side = "far"
sensors = [{bob}]
clips = ["16_36"]
"""


def _sensors(station: int) -> str:
    return ", ".join(f'"st{station}:{i}"' for i in range(6))


def _proc_usage(pid: int) -> tuple[float, float]:
    """(CPU seconds user+system, resident MB) of a process, from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    cpu_s = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    rss_kb = int(re.search(r"VmRSS:\s+(\d+)", Path(f"/proc/{pid}/status").read_text())[1])
    return cpu_s, rss_kb / 1024


def measure(workdir: Path, config: str, seconds: float, warmup_s: float = 10.0) -> dict:
    """Run the gateway on ``config`` and measure it over ``seconds`` after ``warmup_s``."""
    (workdir / "court.toml").write_text(config)
    gateway = subprocess.Popen([sys.executable, "-m", "gateway.cli", "gateway", "--config", "court.toml"],
                               cwd=workdir, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        while not re.match(r"gateway listening on", gateway.stdout.readline()):
            if gateway.poll() is not None:
                raise RuntimeError("gateway exited")
        time.sleep(warmup_s)
        cpu0, _ = _proc_usage(gateway.pid)
        t0 = time.monotonic()
        peak_mb = 0.0
        while time.monotonic() - t0 < seconds:
            time.sleep(1.0)
            peak_mb = max(peak_mb, _proc_usage(gateway.pid)[1])
        cpu1, _ = _proc_usage(gateway.pid)
        return {"cpu_pct": 100.0 * (cpu1 - cpu0) / (time.monotonic() - t0), "rss_mb": peak_mb}
    finally:
        gateway.terminate()
        gateway.wait(30)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        subprocess.run([sys.executable, "-m", "gateway.cli", "camera", "synth", "--out", "court.mp4",
                        "--calibration", "court.json", "--truth", "truth.csv", "--seconds", "30", "--fps", "30",
                        "--width", "640", "--height", "360", "--opponent"], cwd=work, check=True,
                       capture_output=True)
        athletes = ATHLETES.format(alice=_sensors(1), bob=_sensors(2))
        (work / "stations.toml").write_text("[stations]\nemulate = 2\n" + athletes)
        stations = subprocess.Popen([sys.executable, "-c", STATIONS_SCRIPT, "stations.toml"], cwd=work,
                                    stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        try:
            paths = json.loads(stations.stdout.readline())
            ports = "[stations]\nports = [" + ", ".join(f'"{p}"' for p in paths) + "]\n"
            camera = '[camera]\nsource = "court.mp4"\ncourt = "court.json"\nloop = true\n'
            rows = {
                "baseline: 1 athlete, no camera": measure(work, 'listen = "127.0.0.9:0"\n' + ports, args.seconds),
                "2 athletes x 6 x 100 Hz + camera": measure(
                    work, 'listen = "127.0.0.9:0"\n' + ports + camera + athletes, args.seconds),
            }
        finally:
            stations.stdin.close()
            stations.wait(30)
    print(f"gateway process over {args.seconds:.0f} s (2 stations x 6 sensors x 100 Hz from another process; camera "
          "640x360 @ 30 fps, both players)")
    print(f"{'configuration':36s} {'CPU % of a core':>16s} {'peak RSS MB':>12s}")
    for name, row in rows.items():
        print(f"{name:36s} {row['cpu_pct']:16.1f} {row['rss_mb']:12.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
