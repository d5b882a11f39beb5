"""IMU-camera lag check: cross-correlate an event signal seen by both (a jump, a tap, a clap).

Why cross-correlation rather than first-threshold-crossing: it uses the whole shape of the event, is insensitive to
the two signals' different units and gains (both are z-scored), and gives a confidence (the peak's Pearson
correlation). The lag is refined below the resampling step by fitting a parabola through the peak and its two
neighbours.

Convention: ``lag_s > 0`` means the *other* stream's timestamps are late, ``other(t) ~ ref(t - lag_s)``; subtract
``lag_s`` from the other stream's timestamps to align it with the reference.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

from gateway.camera.court_calibration import CourtCalibration


@dataclass(frozen=True)
class LagEstimate:
    """``lag_s`` (see module docstring), ``correlation`` at the peak (-1..1), resampling ``rate_hz``."""

    lag_s: float
    correlation: float
    rate_hz: float


def imu_event_signal(t_s: np.ndarray, acc_g: np.ndarray, highpass_window_s: float = 1.0) -> np.ndarray:
    """|a| minus its moving mean over ``highpass_window_s`` (g): impacts, take-offs and free fall stand out,
    gravity and slow posture changes do not. ``acc_g`` (N, 3) specific force in g at times ``t_s`` (N,)."""
    magnitude = np.linalg.norm(np.asarray(acc_g, float), axis=1)
    n = max(1, int(round(highpass_window_s / np.median(np.diff(t_s)))))
    kernel = np.ones(n) / n
    padded = np.pad(magnitude, (n // 2, n - 1 - n // 2), mode="edge")
    return magnitude - np.convolve(padded, kernel, mode="valid")


def camera_event_signal(t_s: np.ndarray, feature: np.ndarray, window_frames: int = 7) -> np.ndarray:
    """Second derivative of a per-frame scalar ``feature`` (Savitzky-Golay, cubic, ``window_frames``), per s^2.

    Pick a feature that moves with the event, e.g. :func:`upward_image_displacement_px` for a jump (its second
    derivative is the image-space vertical acceleration, the camera's view of what the trunk IMU measures).
    NaNs (frames without a blob) are filled by linear interpolation first. Assumes roughly even frame spacing
    (the derivative is scaled by the median interval)."""
    t = np.asarray(t_s, float)
    values = np.asarray(feature, float)
    good = np.isfinite(values)
    if good.sum() < window_frames:
        raise ValueError(f"need at least {window_frames} frames with a detection, got {int(good.sum())}")
    values = np.interp(t, t[good], values[good])
    dt = float(np.median(np.diff(t)))
    return savgol_filter(values, window_frames, 3, deriv=2, delta=dt)


def upward_image_displacement_px(calibration: CourtCalibration, centroid_px: np.ndarray) -> np.ndarray:
    """Per-frame displacement (N,) px of the blob centroid along the image direction of "up" at the player,
    relative to the first frame: rises when the body lifts off (a jump), whatever the camera orientation."""
    centroid = np.asarray(centroid_px, float).reshape(-1, 2)
    good = np.isfinite(centroid).all(axis=1)
    ref = np.nanmedian(centroid, axis=0)
    up = -calibration.image_down_directions(ref[None])[0]
    out = np.full(len(centroid), np.nan)
    out[good] = (centroid[good] - centroid[good][0]) @ up
    return out


def _resample(t_s: np.ndarray, values: np.ndarray, grid_s: np.ndarray) -> np.ndarray:
    return np.interp(grid_s, t_s, values, left=np.nan, right=np.nan)


def estimate_lag(
    t_ref_s: np.ndarray, ref: np.ndarray, t_other_s: np.ndarray, other: np.ndarray,
    *, max_lag_s: float = 0.5, rate_hz: float | None = None,
) -> LagEstimate:
    """Lag of ``other`` behind ``ref`` by normalised cross-correlation on a common grid at ``rate_hz`` (default:
    the faster stream's median rate), searched over ``[-max_lag_s, max_lag_s]``, refined by a parabola."""
    t_ref, t_other = np.asarray(t_ref_s, float), np.asarray(t_other_s, float)
    if rate_hz is None:
        rate_hz = 1.0 / min(np.median(np.diff(t_ref)), np.median(np.diff(t_other)))
    dt = 1.0 / rate_hz
    m = int(np.ceil(max_lag_s / dt))
    grid = np.arange(t_ref[0], t_ref[-1], dt)
    if len(grid) < 4:
        raise ValueError("reference signal too short to correlate")
    ref_g = _resample(t_ref, np.asarray(ref, float), grid)
    ref_z = (ref_g - ref_g.mean()) / (ref_g.std() or 1.0)
    ext = np.arange(-m, len(grid) + m) * dt + grid[0]
    other_e = _resample(t_other, np.asarray(other, float), ext)
    valid = np.isfinite(other_e)
    if valid.sum() < len(grid) // 2:
        raise ValueError("the two signals hardly overlap in time; widen the recording or max_lag_s")
    other_e = np.where(valid, other_e, np.nanmean(other_e))
    n = len(grid)
    cumsum = np.concatenate([[0.0], np.cumsum(other_e)])
    cumsq = np.concatenate([[0.0], np.cumsum(other_e**2)])
    win_mean = (cumsum[n:] - cumsum[:-n]) / n
    win_std = np.sqrt(np.maximum((cumsq[n:] - cumsq[:-n]) / n - win_mean**2, 1e-18))
    corr = np.correlate(other_e, ref_z, mode="valid") / (n * win_std)  # Pearson per shift (ref_z has mean 0)
    k = int(np.argmax(corr))
    offset = 0.0
    if 0 < k < len(corr) - 1:
        a, b, c = corr[k - 1], corr[k], corr[k + 1]
        denom = a - 2 * b + c
        offset = 0.5 * (a - c) / denom if denom < 0 else 0.0
    return LagEstimate(float((k + offset - m) * dt), float(corr[k]), float(rate_hz))


def jump_lag(t_imu_s: np.ndarray, trunk_acc_g: np.ndarray, t_cam_s: np.ndarray, centroid_px: np.ndarray,
             calibration: CourtCalibration, max_lag_s: float = 0.5) -> LagEstimate:
    """Camera lag behind the IMU from a jump (or jumps) seen by a trunk accelerometer and by the tracker.

    ``trunk_acc_g`` (N, 3) at ``t_imu_s``; ``t_cam_s`` and ``centroid_px`` (M, 2) from the tracker's records
    (``TrackRecord.t_host_s``, ``.centroid_px``). Subtract ``lag_s`` from camera times to align them."""
    camera = camera_event_signal(t_cam_s, upward_image_displacement_px(calibration, centroid_px))
    return estimate_lag(t_imu_s, imu_event_signal(t_imu_s, trunk_acc_g), t_cam_s, camera, max_lag_s=max_lag_s)
