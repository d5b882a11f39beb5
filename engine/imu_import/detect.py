"""What a recorded IMU file does not say reliably: its acceleration unit and its quaternion layout.

Both are read off the data and can be overridden; a stated value the data contradicts is refused.

* **Units.** A still accelerometer reads 1 g whatever its orientation; over 1 s windows the mean reading is
  still ~1 g while the sensor moves (linear acceleration averages out). So the median over windows of
  ``|mean a|`` tells g (~1), m/s² (~9.81) and mg (~1000) apart; the bands [0.7, 1.4] g do not overlap. m/s² is converted, never
  taken as g (the issue that motivated this module: m/s² accepted as g gives readings ~10x too large).
* **Quaternion layout.** Unit norm (checked per row first, `engine.imu_import.orientations`) says that four
  columns are a rotation at all. Which column is the scalar
  part (w first or last) and whether the quaternion turns sensor axes into the world or the reverse is read from
  gravity: rotated into the world by the right hypothesis, the specific force of still samples points the same
  way (world up) whatever the sensor's orientation; under a wrong one it follows the sensor around. The
  hypothesis whose stillness-weighted mean world-frame specific force is longest (~1 g; linear acceleration and
  noise average out) *and* lies along a world axis (every AHRS world is level: Z up in ENU/NWU, Z down in NED,
  Y up in game engines; a wrong layout points "up" anywhere) wins: score = |mean| x max |component of its
  direction|; if the sensor barely turned, all hypotheses agree and the layout cannot be told,
  which is an error asking for ``--quat-order``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

from engine.errors import CourtsideError
from engine.mocap import quaternions as quat
from engine.mocap.sensors import GRAVITY_MPS2

# unit name -> factor that turns it into g; the at-rest band of |a| is REST_BAND_G in that unit
UNITS_TO_G = {"g": 1.0, "m/s2": 1.0 / GRAVITY_MPS2, "mg": 1e-3}
REST_BAND_G = (0.7, 1.4)  # wide: a foot sensor in a walk averages ~1.3 g over 1 s windows
QUAT_ORDERS = ("wxyz", "xyzw")
STILL_WINDOW_S = 0.25
STILL_RELATIVE_STD = 0.03  # std of |a| and of each axis over the window, relative to the at-rest norm


class DetectionError(CourtsideError):
    """The data contradicts a stated unit/layout, or cannot tell one: the message says which and what to give."""


def stillness_std(acc: np.ndarray, rate_hz: float, window_s: float = STILL_WINDOW_S) -> np.ndarray:
    """Per sample, the larger of the centred-window std of |a| and the largest per-axis std (same unit as acc).

    Why both: |a| ignores slow rotation, per-axis std catches it (same rule as the calibration wizard)."""
    a = np.asarray(acc, float)
    size = max(3, int(round(window_s * rate_hz)) | 1)
    norm = np.linalg.norm(a, axis=1)
    stacked = np.column_stack([norm, a])
    mean = uniform_filter1d(stacked, size, axis=0, mode="nearest")
    var = uniform_filter1d(stacked**2, size, axis=0, mode="nearest") - mean**2
    return np.sqrt(np.clip(var, 0.0, None)).max(axis=1)


def quasi_static(acc: np.ndarray, rate_hz: float) -> np.ndarray:
    """Boolean mask of quasi-static samples (unit-free: thresholds relative to the median |a|)."""
    a = np.asarray(acc, float)
    finite = np.all(np.isfinite(a), axis=1)
    scale = float(np.median(np.linalg.norm(a[finite], axis=1))) if finite.any() else 1.0
    std = stillness_std(np.where(finite[:, None], a, 0.0), rate_hz)
    return finite & (std <= STILL_RELATIVE_STD * scale)


@dataclass(frozen=True)
class UnitsResult:
    units: str
    to_g: float
    rest_norm: float  # median |a| at rest, in the file's unit
    detected: str  # what the data says ("g", "m/s2", "mg" or "unknown")
    still_fraction: float


def detect_units(acc: np.ndarray, rate_hz: float, stated: str = "auto", what: str = "acceleration") -> UnitsResult:
    """Unit of ``acc`` (N, 3) from |a| at rest; ``stated`` ("auto", "g", "m/s2", "mg") must agree with it."""
    a = np.asarray(acc, float)
    finite = a[np.all(np.isfinite(a), axis=1)]
    if len(finite) < 3:
        raise DetectionError(f"{what}: fewer than 3 finite samples")
    still = quasi_static(a, rate_hz)
    # |mean a| over 1 s windows: exactly the still norm where the sensor rests, and still ~1 g while it moves
    # (linear acceleration averages out), so it also works on takes that are never still
    n = max(1, min(len(finite), int(round(rate_hz))))
    windows = finite[: len(finite) // n * n].reshape(-1, n, 3).mean(axis=1)
    rest = float(np.median(np.linalg.norm(windows, axis=1)))
    detected = next((u for u, k in UNITS_TO_G.items() if REST_BAND_G[0] <= rest * k <= REST_BAND_G[1]), "unknown")
    if stated not in ("auto", *UNITS_TO_G):
        raise DetectionError(f"unknown unit {stated!r}; known: auto, {', '.join(UNITS_TO_G)}")
    if stated == "auto":
        if detected == "unknown":
            raise DetectionError(f"{what}: |a| at rest is {rest:.4g}, which is neither ~1 g, ~9.81 m/s2 nor "
                                 "~1000 mg: give the unit with --units (and check the columns)")
        stated = detected
    elif detected != stated:
        in_g = rest * UNITS_TO_G[stated]
        raise DetectionError(f"{what}: stated unit {stated} but |a| at rest is {rest:.4g} "
                             f"(= {in_g:.3g} g in that unit, not ~1 g)"
                             + (f": the data is in {detected}" if detected != "unknown" else ""))
    return UnitsResult(stated, UNITS_TO_G[stated], rest, detected, float(still.mean()))


@dataclass(frozen=True)
class QuatLayout:
    order: str  # column order in the file: "wxyz" or "xyzw"
    sensor_to_world: bool  # True: q rotates sensor axes into the world (Xsens, x-IMU3)
    concentration: float  # |weighted mean world specific force| (g) x its alignment with a world axis (1 = perfect)
    runner_up: float
    world_up: np.ndarray  # the device world's up direction (e.g. +Z for Xsens and x-IMU3)


def to_wxyz(q_file: np.ndarray, order: str) -> np.ndarray:
    """Reorder quaternion columns to (w, x, y, z)."""
    q = np.asarray(q_file, float)
    return q if order == "wxyz" else q[..., [3, 0, 1, 2]]


def layout_scores(q_file: np.ndarray, acc_g: np.ndarray, rate_hz: float
                  ) -> dict[tuple[str, bool], tuple[float, np.ndarray]]:
    """Score and world-up direction of every layout hypothesis ``(order, sensor_to_world)`` for one sensor.
    ``q_file``: unit rows or NaN (missing), as `orientations.orientation_rows` leaves them."""
    a = np.asarray(acc_g, float)
    q_file = np.asarray(q_file, float)
    ok = np.all(np.isfinite(a), axis=1) & np.all(np.isfinite(q_file), axis=1)
    weights = 1.0 / (stillness_std(np.where(ok[:, None], a, 0.0), rate_hz)[ok] ** 2 + 0.05**2)
    out = {}
    for order in QUAT_ORDERS:
        rot = quat.to_matrix(to_wxyz(q_file[ok], order))
        for s2w in (True, False):
            world = np.einsum("nij,nj->ni", rot, a[ok]) if s2w else np.einsum("nji,nj->ni", rot, a[ok])
            mean = (weights[:, None] * world).sum(axis=0) / weights.sum()
            up = mean / max(np.linalg.norm(mean), 1e-12)
            # consistency (~1 g) times alignment of the world up with a world axis (AHRS worlds are level)
            out[(order, s2w)] = (float(np.linalg.norm(mean) * np.abs(up).max()), up)
    return out


def detect_quat_layout(per_sensor: list[dict[tuple[str, bool], tuple[float, np.ndarray]]], stated: str = "auto",
                       margin: float = 0.02) -> QuatLayout:
    """One layout for all quaternion columns of a file (they come from one tool): the hypothesis with the best
    mean score over its sensors (:func:`layout_scores`); ``stated`` restricts the column order."""
    if stated not in ("auto", *QUAT_ORDERS):
        raise DetectionError(f"unknown quaternion order {stated!r}; known: auto, {', '.join(QUAT_ORDERS)}")
    totals = sorted(((float(np.mean([s[h][0] for s in per_sensor])), h) for h in per_sensor[0]
                     if stated in ("auto", h[0])), key=lambda x: -x[0])
    (best, hyp), (runner, other) = totals[0], totals[1]
    if best - runner < margin and hyp[0] != other[0]:
        raise DetectionError(f"quaternions: cannot tell w-first from w-last (scores {best:.3f} vs {runner:.3f}: "
                             "the sensors barely turned); give --quat-order")
    ups = np.array([s[hyp][1] for s in per_sensor])
    return QuatLayout(hyp[0], hyp[1], best, runner, ups.mean(axis=0) / np.linalg.norm(ups.mean(axis=0)))
