"""Cost of root fusion (engine/graph/root_fusion.py) per decided frame, live and batch.

A 60 s walk at 30 Hz with a 5 cm / 10 deg camera fix every frame: the fixed-lag smoother decides one frame per
push (an RTS pass back over the lag each time), the batch smoother decides the whole take at once. Printed: CPU
microseconds per frame, and each against the causal filter (lag 0) measured in the same process; plus the
root error against the truth (the reason for the lag).

    .venv/bin/python bench/bench_root_fusion.py
"""
from __future__ import annotations

import time

import numpy as np

from engine.graph.geometry import wrap_angle
from engine.graph.root_fusion import RootFuser, RootFusion, fuse_track

FPS = 30.0


def walk(n: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    t = np.arange(n) / FPS
    heading = 0.6 * np.sin(0.3 * t)
    speed = 1.2 + 0.3 * np.sin(2 * np.pi * 1.8 * t)  # stride rhythm
    step = speed[:, None] * np.stack([np.sin(heading), np.cos(heading)], axis=1) / FPS
    ground = np.cumsum(step, axis=0)
    return (ground, heading, ground + rng.normal(0, 0.05, ground.shape),
            heading + rng.normal(0, np.radians(10), n))


def fixed_lag(lag: int, fixes: tuple[np.ndarray, np.ndarray], path: tuple[np.ndarray, np.ndarray]):
    fuser = RootFuser(RootFusion(), FPS)
    out_g, out_h = [], []
    c0 = time.process_time()
    n = len(path[1])
    for t in range(n):
        fuser.push(fixes[0][t], fixes[1][t])
        if t >= lag:
            g, h = fuser.decide(path[0][t - lag:t - lag + 1], path[1][t - lag:t - lag + 1])
            out_g.append(g)
            out_h.append(h)
    g, h = fuser.decide(path[0][n - lag:], path[1][n - lag:]) if lag else (np.zeros((0, 2)), np.zeros(0))
    cpu = time.process_time() - c0
    return cpu / n, np.concatenate(out_g + [g]), np.concatenate(out_h + [h])


def main() -> None:
    n = int(60 * FPS)
    ground, heading, cam_g, cam_h = walk(n, np.random.default_rng(0))
    path = (ground, heading)  # used only where the camera is absent (never here)
    rows = []
    for name, lag in (("causal (lag 0)", 0), ("lag 0.2 s", 6), ("lag 2 s", 60)):
        rows.append((name, *fixed_lag(lag, (cam_g, cam_h), path)))
    c0 = time.process_time()
    bg, bh = fuse_track(RootFusion(), FPS, cam_g, cam_h, ground, heading)
    rows.append(("batch (whole take)", (time.process_time() - c0) / n, bg, bh))
    base = rows[0][1]
    print(f"{n} frames (60 s at 30 Hz), camera 5 cm / 10 deg every frame; raw fixes: "
          f"{100 * np.linalg.norm(cam_g - ground, axis=1).mean():.2f} cm, "
          f"{np.degrees(np.abs(wrap_angle(cam_h - heading))).mean():.2f} deg")
    print(f"{'smoother':20s} {'us/frame':>9s} {'vs causal':>10s} {'root cm':>8s} {'head deg':>9s}")
    for name, per_frame, g, h in rows:
        print(f"{name:20s} {1e6 * per_frame:9.0f} {per_frame / base:9.1f}x "
              f"{100 * np.linalg.norm(g - ground, axis=1).mean():8.2f} "
              f"{np.degrees(np.abs(wrap_angle(h - heading))).mean():9.2f}")


if __name__ == "__main__":
    main()
