"""Seed 002 benchmark: joint centres by GDKE, GDKE + geometric refinement (fit_joint), iterative least squares
and SCoRE, all on the same data in the same run.

Tables:
  1. full spheres: |c − c0|·√N/σ (Eq. 7 predicts ≈ 2.9) and µs per fit, N = 10 … 10⁴;
  2. spherical caps of half-angle 90° / 60° / 30° (a real joint sweeps a partial arc): the closed form's bias
     grows with N there, the geometric fits' error does not;
  3. rigid-cluster functional trials (4-marker parent moving in 6 DOF, 5-marker child cluster ±20° / ±35°,
     1 and 2 mm marker noise, 600 frames): median centre error in the parent frame and ms per joint.
Peers: "lstsq LM" = scipy least_squares (Levenberg-Marquardt) on the geometric residual |x − c| − R_m from the
centroid, the iterative least squares of the issue; "SCoRE" = engine.skeleton_fit.score (Ehrig et al. 2006,
implemented from the paper: biobuddy's SCoRE installs from PyPI but does not import without matplotlib).
Times are CPU time, best of 3.

    .venv/bin/python bench/bench_sphere_fit.py [--trials 100] [--quick]
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.optimize import least_squares

from engine.skeleton_fit.frames import frame_from_three, to_local
from engine.skeleton_fit.gdke import JointFitConfig, fit_joint, kasa_lstsq_centre, sphere_fit
from engine.skeleton_fit.score import cluster_poses, score_centre
from engine.skeleton_fit.synthetic import functional_trial, spherical_cap

GDKE_ONLY = JointFitConfig(static_std=0.0, refine_iterations=0)
REFINED = JointFitConfig(static_std=0.0)


def lstsq_lm(trajectories: list[np.ndarray]) -> np.ndarray:
    """Iterative geometric least squares: Σ (|x_i − c| − R_m)² over c and one radius per marker, scipy's
    Levenberg-Marquardt from the centroid (no closed-form start)."""
    x = np.concatenate(trajectories)
    owner = np.concatenate([np.full(len(t), m) for m, t in enumerate(trajectories)])
    start = x.mean(axis=0)
    radii = [np.linalg.norm(t - start, axis=1).mean() for t in trajectories]
    fit = least_squares(lambda p: np.linalg.norm(x - p[:3], axis=1) - p[3:][owner], np.append(start, radii),
                        method="lm")
    return fit.x[:3]


def _cpu_us(fn, inputs: list, repeats: int = 3) -> float:
    """CPU µs per call, best of ``repeats`` (CPU time and the minimum damp a shared machine's noise)."""
    best = np.inf
    for _ in range(repeats):
        start = time.process_time()
        for item in inputs:
            fn(item)
        best = min(best, time.process_time() - start)
    return best / len(inputs) * 1e6


def sphere_tables(trials: int, quick: bool) -> None:
    rng = np.random.default_rng(0)
    methods = {
        "gdke": lambda p: sphere_fit(p).centre,
        "kasa_lstsq": kasa_lstsq_centre,
        "fit_joint": lambda p: fit_joint(p, REFINED).centre,
        "lstsq_lm": lambda p: lstsq_lm([p]),
    }
    sigma, radius = 0.002, 0.3
    ns = (10, 100, 1000) if quick else (10, 100, 1000, 10000)
    for title, half in (("1. full sphere", 180.0), ("2a. cap 90°", 90.0), ("2b. cap 60°", 60.0),
                        ("2c. cap 30°", 30.0)):
        print(f"\n{title} (σ = 2 mm, R = 0.3 m, {trials} trials; error factor = mean |c − c0|·√N/σ)")
        print(f"{'N':>6} " + "".join(f"{m + ' err':>16}{'µs':>8}" for m in methods)
              + f"{'fit_joint/lm err':>18}{'lm/fit_joint µs':>17}")
        for n in ns:
            data = [spherical_cap(rng, n, half, radius, sigma) for _ in range(trials)]
            cells, err, us = "", {}, {}
            for name, fn in methods.items():
                err[name] = np.mean([np.linalg.norm(fn(p)) for p in data]) * np.sqrt(n) / sigma
                us[name] = _cpu_us(fn, data)
                cells += f"{err[name]:>16.2f}{us[name]:>8.0f}"
            print(f"{n:>6} {cells}{err['fit_joint'] / err['lstsq_lm']:>18.2f}{us['lstsq_lm'] / us['fit_joint']:>16.1f}x")


def functional_table(trials: int) -> None:
    print(f"\n3. functional trials (600 frames, {trials} trials): median centre error (mm) in the parent frame, "
          "ms per joint")
    print(f"{'trial':<14}{'gdke':>8}{'fit_joint':>11}{'lstsq_lm':>10}{'SCoRE':>8}"
          f"{'gdke ms':>9}{'fit_joint ms':>13}{'lm ms':>8}{'SCoRE ms':>10}{'fj/lm err':>10}{'lm/fj time':>11}"
          f"{'arc°':>6}{'expected mm':>12}")
    rng = np.random.default_rng(1)
    for amplitude, noise in ((20, 0.002), (20, 0.001), (35, 0.002), (35, 0.001)):
        cases = []
        for _ in range(trials):
            trial = functional_trial(rng, amplitude, noise)
            parent = frame_from_three(*(trial.parent[:, i] for i in range(3)))
            clean = frame_from_three(*(trial.parent_clean[:, i] for i in range(3)))
            truth = to_local(trial.centre_world, *clean).mean(axis=0)
            local = [to_local(trial.child[:, m], *parent) for m in range(trial.child.shape[1])]
            cases.append((local, parent, trial.child, truth))
        methods = {
            "gdke": lambda c: fit_joint(c[0], GDKE_ONLY).centre,
            "fit_joint": lambda c: fit_joint(c[0], REFINED).centre,
            "lstsq_lm": lambda c: lstsq_lm(c[0]),
            "score": lambda c: score_centre(*c[1], *cluster_poses(c[2]))[0],
        }
        err = {k: 1000 * np.median([np.linalg.norm(fn(c) - c[3]) for c in cases]) for k, fn in methods.items()}
        ms = {k: _cpu_us(fn, cases, repeats=2) / 1000 for k, fn in methods.items()}
        fits = [fit_joint(c[0], REFINED) for c in cases]
        print(f"±{amplitude}° {1000 * noise:.0f} mm    " + "".join(f"{err[k]:>{w}.2f}" for k, w in
              zip(methods, (8, 11, 10, 8)))
              + "".join(f"{ms[k]:>{w}.2f}" for k, w in zip(methods, (9, 13, 8, 10)))
              + f"{err['fit_joint'] / err['lstsq_lm']:>10.2f}{ms['lstsq_lm'] / ms['fit_joint']:>10.1f}x"
              + f"{np.median([f.arc_deg for f in fits]):>6.0f}{1000 * np.median([f.expected_error for f in fits]):>12.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=100, help="trials per cell of tables 1-2 (table 3: 30)")
    parser.add_argument("--quick", action="store_true", help="N up to 1000 and 10 functional trials")
    args = parser.parse_args()
    sphere_tables(args.trials, args.quick)
    functional_table(10 if args.quick else 30)


if __name__ == "__main__":
    main()
