"""Benchmarks for engine.mocap and the seed-000 sensor-error calibration.

Run: `python -m engine.mocap.bench [--shared /work/shared/mocap]`. Prints a table of parse / cache / FK /
virtual-sensor throughput (frames per second of wall time, and each stage's ratio to FK measured in the
same run, so the numbers compare across machines) and re-solves `SEED000_NOISE_G`."""
from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from engine.mocap.clips import load_clip, load_database, sample_clips
from engine.mocap.sensors import (REAL_GAP_G2, SEED000_SENSORS, SensorErrorModel, mean_squared_error_g2,
                                  standard_placements, virtual_accelerometers)
from engine.mocap.skeleton import Motion, forward_kinematics

CALIBRATION_CLIPS = ("16_11", "16_35", "16_01", "135_04")
TARGET_MSE_G2 = 1.6


def _timed(fn, repeat: int = 3) -> float:
    """Best-of-`repeat` wall time in seconds (best, not mean: the machine is shared)."""
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def _calibration_readings() -> list[np.ndarray]:
    clean = []
    for name in CALIBRATION_CLIPS:
        motion = load_clip(sample_clips()[name], fps=30)
        clean.append(virtual_accelerometers(motion, standard_placements(motion.skeleton, SEED000_SENSORS), clip_g=12))
    return clean


def _gap(model: SensorErrorModel, clean: list[np.ndarray], seed: int) -> float:
    rng = np.random.default_rng(seed)
    return float(np.mean([mean_squared_error_g2(model.apply(c, 30, rng), c) for c in clean]))


def calibrate_seed000_noise(seed: int = 0) -> tuple[float, float]:
    """Solve the white-noise level that brings the seed-000 preset's gap to TARGET_MSE_G2.

    Independent zero-mean noise adds 3 sd² to the per-vector MSE, so with every other term fixed
    noise_g = sqrt((target - mse_without_noise) / 3). Returns (noise_g, check_mse_with_that_noise)."""
    clean = _calibration_readings()
    base = SensorErrorModel.seed000()
    without = _gap(base.with_noise(0.0), clean, seed)
    noise = float(np.sqrt(max(TARGET_MSE_G2 - without, 0.0) / 3))
    return noise, _gap(base.with_noise(noise), clean, seed)


def calibrate_real_noise(seed: int = 0) -> tuple[float, float]:
    """Solve `noise_rel` of `SensorErrorModel.measured_real()` for a gap of REAL_GAP_G2: the signal-scaled
    noise adds 3 E[(noise_g + r |dyn|)²] to the MSE; the quadratic in r is solved on the calibration clips.
    Returns (noise_rel, check_mse_with_it)."""
    clean = _calibration_readings()
    base = SensorErrorModel.measured_real()
    without = _gap(replace(base, noise_g=0.0, noise_rel=0.0), clean, seed)
    dyn = np.concatenate([np.linalg.norm(c - c.mean(axis=0), axis=-1).ravel() for c in clean])
    # 3 (n² + 2 n r E|dyn| + r² E|dyn|²) = target - without
    a, b, c = 3 * np.mean(dyn ** 2), 6 * base.noise_g * np.mean(dyn), 3 * base.noise_g ** 2 - (REAL_GAP_G2 - without)
    r = float((-b + np.sqrt(max(b * b - 4 * a * c, 0.0))) / (2 * a))
    return r, _gap(replace(base, noise_rel=r), clean, seed)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shared", type=Path, default=Path("/work/shared/mocap"),
                        help="full mocap set for the Bandai BVH timing (skipped if absent)")
    args = parser.parse_args(argv)

    clips = sample_clips()
    amc_paths = list(clips.values())
    motions = [load_clip(p) for p in amc_paths]
    n120 = sum(m.n_frames for m in motions)
    rows: list[tuple[str, int, float]] = []
    rows.append(("parse ASF/AMC (shipped, 120 Hz)", n120, _timed(lambda: [load_clip(p) for p in amc_paths])))
    subject16 = [m for m in motions if m.skeleton is motions[-1].skeleton]  # clips sharing one ASF skeleton
    tiles = 5  # ~17k frames, so the vectorised stages are timed well above timer resolution
    big = Motion(subject16[0].skeleton, 120.0, np.concatenate([m.root_positions_m for m in subject16] * tiles),
                 np.concatenate([m.rotations for m in subject16] * tiles))
    rows.append(("forward kinematics (31 bones + tips)", big.n_frames, _timed(lambda: forward_kinematics(big))))
    placements = standard_placements(big.skeleton, SEED000_SENSORS)
    rows.append(("virtual accelerometers x6 (incl. FK)", big.n_frames, _timed(lambda: virtual_accelerometers(big, placements))))
    with tempfile.TemporaryDirectory() as cache:
        load_database(amc_paths, fps=30, cache_dir=cache)
        n30 = sum(m.n_frames for m in load_database(amc_paths, fps=30, cache_dir=cache))
        rows.append(("load_database 30 Hz, cold (parse+resample)", n30,
                     _timed(lambda: load_database(amc_paths, fps=30, use_cache=False))))
        rows.append(("load_database 30 Hz, cached npz", n30, _timed(lambda: load_database(amc_paths, fps=30, cache_dir=cache))))
    bandai = sorted((args.shared / "bandai-namco-2" / "data").glob("*.bvh"))[:100]
    if bandai:
        from engine.mocap.bvh import read_bvh
        n_b = sum(read_bvh(p).n_frames for p in bandai)
        rows.append((f"parse Bandai BVH ({len(bandai)} clips, 30 Hz)", n_b, _timed(lambda: [read_bvh(p) for p in bandai], 1)))

    fk_rate = rows[1][1] / rows[1][2]
    print(f"{'stage':48s} {'frames':>8s} {'seconds':>8s} {'frames/s':>10s} {'x FK time/frame':>15s}")
    for name, frames, seconds in rows:
        rate = frames / seconds
        print(f"{name:48s} {frames:8d} {seconds:8.3f} {rate:10.0f} {fk_rate / rate:15.2f}")

    noise, check = calibrate_seed000_noise()
    print(f"\nseed-000 error model: noise_g solved = {noise:.3f} g (shipped preset uses "
          f"{SensorErrorModel.seed000().noise_g:.3f}); MSE with it = {check:.3f} g^2 (target {TARGET_MSE_G2})")
    rel, check = calibrate_real_noise()
    print(f"measured-real error model: noise_rel solved = {rel:.3f} (shipped preset uses "
          f"{SensorErrorModel.measured_real().noise_rel:.3f}); MSE with it = {check:.3f} g^2 (target {REAL_GAP_G2})")


if __name__ == "__main__":
    main()
