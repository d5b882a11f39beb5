"""Benchmark of the camera + calibration part: ``python -m gateway.camera.bench [--quick]``.

Prints tables (numbers quoted in docs/camera-calibration.md):
1. tracking accuracy vs ground truth per scenario and ground-point method (each frame rendered once, all
   trackers fed the same frames);
2. sensitivity of the parallax-corrected centroid to the assumed centroid height;
3. cost per frame: tracking vs rendering (the baseline measured in the same run);
4. IMU-camera lag check on a rendered jump for several injected latencies;
5. calibration wizard: rotation error over random emulated subjects, and push throughput;
6. two athletes: identity swaps, losses and position error per athlete over scripted changeover rallies.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from engine.mocap import load_clip, sample_clips
from gateway.calibration import CalibrationWizard, SegmentSpec, minimal_rotation, rotation_angle_deg
from gateway.camera import (
    COURT_KEYPOINTS_M, CameraImperfections, CourtCalibration, PlayerPath, PlayerTracker, SyntheticCourtCamera,
    TrackerConfig, camera_event_signal, default_court_camera, estimate_lag, imu_event_signal, jump_lift_m,
    scripted_rally_path, upward_image_displacement_px,
)
from gateway.camera.identity import score_tracks
from gateway.camera.mocap_body import MocapBody
from gateway.camera.paths import changeover_rally_paths
from gateway.camera.tracker import MultiPlayerTracker
from gateway.camera.paths import GRAVITY_MPS2

REALISTIC = CameraImperfections(drop_probability=0.05, jitter_s=0.002)


def calibrations(camera, noise_px: float = 0.5):
    names = list(COURT_KEYPOINTS_M)
    court = np.array([COURT_KEYPOINTS_M[n] for n in names])
    clicks = camera.project(np.column_stack([court, np.zeros(len(court))]))
    clicks += np.random.default_rng(0).normal(0, noise_px, clicks.shape)
    with_pose = CourtCalibration.fit(clicks, names=names, image_size=camera.image_size,
                                     camera_matrix=camera.camera_matrix)
    homography_only = CourtCalibration.fit(clicks, names=names, image_size=camera.image_size)
    return with_pose, homography_only


LIGHTING = CameraImperfections(drop_probability=0.05, jitter_s=0.002, drift=0.15, drift_tilt=0.25, drift_period_s=16.0)


def scenarios(quick: bool):
    """(name, path, body, imperfections) of each benchmark scene."""
    yield "rally seed 4 (scripted)", scripted_rally_path(6.0 if quick else 12.0, seed=4), None, REALISTIC
    if not quick:
        yield "rally seed 8 (scripted)", scripted_rally_path(12.0, seed=8), None, REALISTIC
        yield "rally 8 + cloud, light tilt", scripted_rally_path(12.0, seed=8), None, LIGHTING
    clips = ("16_05", "16_45") if quick else ("16_05", "16_21", "16_45", "135_04")
    for clip in clips:
        body = MocapBody(load_clip(sample_clips()[clip], fps=30.0), (1.0, -8.0))
        yield f"CMU {clip} (mocap)", body.path, body, REALISTIC


def accuracy_table(camera, quick: bool) -> None:
    with_pose, h_only = calibrations(camera)
    methods = {
        "centroid+pose": (with_pose, TrackerConfig(ground_point="centroid")),
        "foot+pose": (with_pose, TrackerConfig(ground_point="foot")),
        "foot, H only": (h_only, TrackerConfig(ground_point="foot")),
    }
    print("\n1. position error vs ground truth (m), 30 fps, 5 % dropped frames, 2 ms timestamp jitter, clicks +-0.5 px"
          "\n   (lighting row: +15 % cloud and +-25 % left-right tilt within 4 s)")
    print(f"{'scenario':28s} {'frames':>6s} " + " ".join(f"{m + ' rms/p95':>24s}" for m in methods) + f" {'detected':>9s}")
    for name, path, body, imperfections in scenarios(quick):
        trackers = {m: PlayerTracker(c, cfg) for m, (c, cfg) in methods.items()}
        errors: dict[str, list[float]] = {m: [] for m in methods}
        on_court = 0
        for frame in SyntheticCourtCamera(path, camera=camera, body=body, imperfections=imperfections, seed=1):
            on_court += frame.truth.visible
            for m, tracker in trackers.items():
                rec = tracker.update(frame)
                if rec is not None and frame.truth.visible:
                    errors[m].append(np.hypot(rec.x_m - frame.truth.x_m, rec.y_m - frame.truth.y_m))
        cells = []
        for m in methods:
            e = np.array(errors[m])
            cells.append(f"{np.sqrt(np.mean(e**2)):.3f} / {np.percentile(e, 95):.3f}".rjust(24))
        detected = len(errors["centroid+pose"]) / max(on_court, 1)
        print(f"{name:28s} {on_court:6d} " + " ".join(cells) + f" {detected:9.1%}")


def height_sensitivity(camera, quick: bool) -> None:
    with_pose, _ = calibrations(camera)
    heights = (0.75, 0.85, 0.9, 0.95, 1.05)
    print("\n2. parallax-corrected centroid: RMS (m) vs assumed centroid height (default 0.9 m)")
    for name, path, body, imperfections in list(scenarios(quick))[:: 2 if quick else 1]:
        if imperfections is LIGHTING:  # same path as the row above; the height effect does not change
            continue
        trackers = {h: PlayerTracker(with_pose, TrackerConfig(ground_point="centroid", centroid_height_m=h))
                    for h in heights}
        errors: dict[float, list[float]] = {h: [] for h in heights}
        for frame in SyntheticCourtCamera(path, camera=camera, body=body, seed=2):
            for h, tracker in trackers.items():
                rec = tracker.update(frame)
                if rec is not None and frame.truth.visible:
                    errors[h].append(np.hypot(rec.x_m - frame.truth.x_m, rec.y_m - frame.truth.y_m))
        print(f"   {name:28s} " + "  ".join(f"h={h:.2f}: {np.sqrt(np.mean(np.square(errors[h]))):.3f}" for h in heights))


def cost_table(camera, quick: bool) -> None:
    with_pose, _ = calibrations(camera)
    n = 90 if quick else 300
    source = SyntheticCourtCamera(scripted_rally_path(n / 30.0, seed=3), camera=camera, seed=3)
    frames, t0 = [], time.perf_counter()
    for _ in range(n):
        frames.append(source.read())
    render_ms = (time.perf_counter() - t0) / n * 1e3
    tracker = PlayerTracker(with_pose)
    t0 = time.perf_counter()
    for frame in frames:
        tracker.update(frame)
    track_ms = (time.perf_counter() - t0) / n * 1e3
    w, h = camera.image_size
    print(f"\n3. cost per {w}x{h} frame: render {render_ms:.1f} ms (baseline), track {track_ms:.1f} ms "
          f"(ratio {track_ms / render_ms:.2f}); tracking alone sustains {1000 / track_ms:.0f} fps on this machine")


def lag_table(camera, quick: bool) -> None:
    with_pose, _ = calibrations(camera)
    t = np.arange(0.0, 4.0, 0.002)
    lift = jump_lift_m(t, ((1.0, 0.35), (2.6, 0.25)))
    path = PlayerPath(t, np.tile([1.0, -8.0], (len(t), 1)), np.zeros(len(t)), lift)
    t_imu = np.arange(0.0, 4.0, 0.01)
    vertical = np.interp(t_imu, t, path.vertical_acceleration_mps2()) / GRAVITY_MPS2
    acc = np.column_stack([np.zeros_like(t_imu), 1 + vertical, np.zeros_like(t_imu)])
    acc += np.random.default_rng(0).normal(0, 0.02, acc.shape)
    imu = imu_event_signal(t_imu, acc)
    print("\n4. IMU-camera lag from two jumps (IMU 100 Hz, camera 30 fps, 2 ms jitter)")
    print(f"   {'injected ms':>12s} {'estimated ms':>13s} {'error ms':>9s} {'peak r':>7s}")
    for latency in ((0.0, 0.08) if quick else (-0.05, 0.0, 0.033, 0.08, 0.15)):
        source = SyntheticCourtCamera(path, camera=camera, seed=3,
                                      imperfections=CameraImperfections(latency_s=latency, jitter_s=0.002))
        tracker = PlayerTracker(with_pose)
        recs = [r for r in (tracker.update(f) for f in source) if r is not None]
        t_cam = np.array([r.t_host_s for r in recs])
        cam = camera_event_signal(t_cam, upward_image_displacement_px(with_pose, np.array([r.centroid_px for r in recs])))
        est = estimate_lag(t_imu, imu, t_cam, cam, max_lag_s=0.3)
        print(f"   {latency * 1e3:12.1f} {est.lag_s * 1e3:13.1f} {(est.lag_s - latency) * 1e3:9.1f} {est.correlation:7.2f}")


def wizard_table(quick: bool) -> None:
    rng = np.random.default_rng(0)
    n_subjects = 10 if quick else 50
    errors, pushes, push_s = [], 0, 0.0
    specs = {f"seg{i}": SegmentSpec(minimal_rotation([0, 1, 0], rng.normal(size=3))) for i in range(6)}
    for _ in range(n_subjects):
        wiz = CalibrationWizard(specs)
        truth = {}
        for i, seg in enumerate(specs):
            axis = np.cross([0, 1, 0], rng.normal(size=3))
            lean = np.tan(np.radians(rng.uniform(5, 25))) * axis / np.linalg.norm(axis)
            tilt = minimal_rotation([0, 1, 0], np.array([0, 1, 0]) + lean)
            truth[f"s{i}"] = tilt @ specs[seg].nominal_rotation
            wiz.assign(f"s{i}", seg)
        wiz.confirm()
        t_all = np.arange(0.0, 5.0, 0.01)
        bias = {sid: rng.normal(0, 0.01, 3) for sid in truth}
        for k in range(0, len(t_all), 5):
            t = t_all[k : k + 5]
            for sid, rot in truth.items():
                acc = np.tile(rot.T @ [0, 1, 0] + bias[sid], (len(t), 1)) + rng.normal(0, 0.005, (len(t), 3))
                t0 = time.perf_counter()
                wiz.push(sid, t, acc)
                push_s += time.perf_counter() - t0
                pushes += 1
            if wiz.step == "placement" and k >= 50:
                wiz.confirm()
        errors += [rotation_angle_deg(wiz.results[s].rotation @ truth[s].T) for s in truth]
    e = np.array(errors)
    print(f"\n5. calibration wizard, {n_subjects} random subjects x 6 sensors (5-25 deg tilt, 0.01 g bias, 0.005 g noise)")
    print(f"   rotation error: mean {e.mean():.2f} deg, p95 {np.percentile(e, 95):.2f} deg, max {e.max():.2f} deg")
    print(f"   push(): {push_s / pushes * 1e6:.0f} us per 5-sample packet -> "
          f"{5 * pushes / push_s:,.0f} samples/s on one core")


def two_athletes_table(camera, quick: bool) -> None:
    with_pose, _ = calibrations(camera)
    margin_m = TrackerConfig().court_margin_m
    print("\n6. two athletes, one track each: scripted changeover rallies (both cross the net 0.6-1.2 m apart;"
          "\n   the far player leaves the view once), 30 fps, 5 % dropped frames, 2 ms jitter")
    print(f"   {'scenario':24s} {'frames':>6s} {'near rms/p95 m':>15s} {'far rms/p95 m':>15s} {'swap frames':>11s} "
          f"{'losses':>7s} {'detected':>9s}")
    for seed in ((1,) if quick else (1, 2, 3)):
        crossings = 8 if quick else 20
        near, far = changeover_rally_paths(crossings, seed=seed, leave_view_after=crossings // 4)
        source = SyntheticCourtCamera(near, camera=camera, imperfections=REALISTIC, seed=seed, opponents=[far])
        tracker = MultiPlayerTracker(with_pose, {"near": "near", "far": "far"})
        scores = score_tracks(source, tracker, {"near": near, "far": far}, margin_m=margin_m)
        cells = [f"{sc.rms_m:.3f} / {np.percentile(sc.errors_m, 95):.3f}".rjust(15) for sc in scores.values()]
        swaps = sum(sc.swap_frames for sc in scores.values())
        losses = "/".join(str(sc.losses) for sc in scores.values())
        detected = min(sc.detected for sc in scores.values())
        print(f"   {f'seed {seed}, {crossings} crossings':24s} {len(scores['near'].statuses):6d} {cells[0]} {cells[1]} "
              f"{swaps:11d} {losses:>7s} {detected:9.1%}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="shorter scenarios (about a minute)")
    parser.add_argument("--only", choices=["two-athletes"], help="run one table only")
    args = parser.parse_args(argv)
    camera = default_court_camera()
    if args.only == "two-athletes":
        two_athletes_table(camera, args.quick)
        return 0
    accuracy_table(camera, args.quick)
    height_sensitivity(camera, args.quick)
    cost_table(camera, args.quick)
    lag_table(camera, args.quick)
    wizard_table(args.quick)
    two_athletes_table(camera, args.quick)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
