"""`courtside import-imu` readers: time to import one minute of seven sensors at 100 Hz in each format (files
written from virtual sensors on a shipped CMU walk, repeated), and the largest error against the virtual truth.

    python bench/bench_import.py
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from engine.imu_import import assemble, read_generic_csv, read_xsens, read_ximu3  # noqa: E402
from engine.mocap import SEED000_SENSORS, standard_placements  # noqa: E402
from bench.support.imu_formats import (Truth, clip, virtual_recording, write_generic_csv,  # noqa: E402
                                             write_mt_exports, write_mvnx, write_ximu3_logger)


def minute(truth: Truth, seconds: float = 60.0) -> Truth:
    reps = int(np.ceil(seconds * truth.fps / len(truth.acc_g)))
    n = int(seconds * truth.fps)
    tile = lambda a: np.concatenate([a] * reps)[:n]  # noqa: E731
    return Truth(tile(truth.acc_g), tile(truth.rot), tile(truth.gyro_rps), truth.fps, truth.names)


def main() -> None:
    motion = clip("16_11", 100.0)
    truth = minute(virtual_recording(motion, standard_placements(motion.skeleton, list(SEED000_SENSORS) + ["right_foot"])))
    ids = [f"00B42D{k:02X}" for k in range(len(truth.names))]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cols = write_generic_csv(tmp / "t.csv", truth, "m/s2", "xyzw")
        write_mvnx(tmp / "t.mvnx", truth)
        write_mt_exports(tmp / "mt", truth, ids)
        write_ximu3_logger(tmp / "xi", truth, [f"{k:08X}" for k in range(len(ids))], truth.names, [0] * len(ids))
        readers = {
            "generic CSV (m/s2, w-last quaternions)": lambda: read_generic_csv(
                tmp / "t.csv", {n: c[0] for n, c in cols.items()}, {n: c[1] for n, c in cols.items()}, time_column="time", time_unit="ms"),
            "Xsens MVNX": lambda: read_xsens(tmp / "t.mvnx")[0],
            "Xsens MT Manager text (7 files)": lambda: read_xsens(tmp / "mt", dict(zip(ids, truth.names)))[0],
            "x-IMU3 data logger (7 devices)": lambda: read_ximu3(tmp / "xi")[0],
        }
        print(f"{'format':40s} {'MB':>6s} {'seconds':>8s} {'samples/s':>10s} {'max error g':>12s}")
        sizes = {"generic": tmp / "t.csv", "Xsens MVNX": tmp / "t.mvnx", "Xsens MT": tmp / "mt", "x-IMU3": tmp / "xi"}
        for name, read in readers.items():
            path = next(p for k, p in sizes.items() if name.startswith(k))
            mb = (sum(f.stat().st_size for f in path.rglob("*") if f.is_file()) if path.is_dir()
                  else path.stat().st_size) / 1e6
            t0 = time.perf_counter()
            take = assemble(read(), "bench")
            dt = time.perf_counter() - t0
            idx = [truth.names.index(n) for n in take.sensor_names]
            err = np.abs(take.acc_g - truth.acc_g[: len(take.acc_g), idx]).max()
            print(f"{name:40s} {mb:6.1f} {dt:8.2f} {take.acc_g.shape[0] * take.acc_g.shape[1] / dt:10.0f} {err:12.1e}")


if __name__ == "__main__":
    main()
