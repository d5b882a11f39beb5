"""Court calibration: homography from clicked court keypoints, its error, and JSON persistence.

Why a homography: the camera is fixed and the court is a plane, so one 3x3 matrix maps every ground pixel to court
metres. It is fitted once per venue from >= 4 clicked line intersections (DLT least squares, or RANSAC when a click
may be wrong) and checked by the reprojection error in pixels *and* in court metres (what the operator cares about).

Optional intrinsics: with the camera matrix (from a checkerboard calibration) the camera pose is recovered with
``cv2.solvePnP`` (planar IPPE). The pose gives the camera centre and the image direction of "down" at any pixel,
which the tracker uses to find a standing player's ground point despite parallax. Without intrinsics the tracker
falls back to image-down.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from gateway.camera.court import keypoints_array
from gateway.camera.errors import CourtCalibrationFileError
from engine.versioned_json import read_versioned_json

SCHEMA = "courtside.court_calibration"
SCHEMA_VERSION = 1


def _apply_homography(h: np.ndarray, points: np.ndarray) -> np.ndarray:
    pts = np.asarray(points, float).reshape(-1, 2)
    homog = np.column_stack([pts, np.ones(len(pts))]) @ h.T
    return homog[:, :2] / homog[:, 2:3]


@dataclass
class CourtCalibration:
    """Court (x, y) m <-> image (u, v) px mapping of one fixed camera.

    ``homography`` maps court to image (``H @ [x, y, 1] ~ [u, v, 1]``). ``rvec``/``tvec`` (court -> camera, OpenCV
    convention) are present only when ``camera_matrix`` was given to :meth:`fit`.
    """

    homography: np.ndarray
    image_size: tuple[int, int]
    image_points_px: np.ndarray
    court_points_m: np.ndarray
    point_names: list[str] = field(default_factory=list)
    camera_matrix: np.ndarray | None = None
    dist_coeffs: np.ndarray | None = None
    rvec: np.ndarray | None = None
    tvec: np.ndarray | None = None

    # ------------------------------------------------------------------ fitting
    @classmethod
    def fit(
        cls,
        image_points_px: np.ndarray,
        court_points_m: np.ndarray | None = None,
        *,
        names: list[str] | None = None,
        image_size: tuple[int, int],
        camera_matrix: np.ndarray | None = None,
        dist_coeffs: np.ndarray | None = None,
        ransac_threshold_px: float | None = None,
    ) -> "CourtCalibration":
        """Fit from N >= 4 clicked pixels and their court coordinates (or keypoint ``names``).

        ``ransac_threshold_px=None`` uses plain DLT least squares over all points; a value uses RANSAC with that
        inlier threshold. Lens distortion, when ``dist_coeffs`` is given, is removed from the clicks first."""
        img = np.asarray(image_points_px, float).reshape(-1, 2)
        if court_points_m is None:
            if names is None:
                raise ValueError("give court_points_m or keypoint names")
            court = keypoints_array(names)
        else:
            court = np.asarray(court_points_m, float).reshape(-1, 2)
        if len(img) != len(court):
            raise ValueError(f"{len(img)} image points but {len(court)} court points")
        if len(img) < 4:
            raise ValueError(f"a homography needs at least 4 point pairs, got {len(img)}")
        undist = cls._undistort(img, camera_matrix, dist_coeffs)
        method = 0 if ransac_threshold_px is None else cv2.RANSAC
        h, _ = cv2.findHomography(court, undist, method, ransac_threshold_px or 3.0)
        if h is None:
            raise ValueError("degenerate point configuration (collinear clicks?): no homography")
        rvec = tvec = None
        if camera_matrix is not None:
            obj = np.column_stack([court, np.zeros(len(court))])
            dist = np.zeros(5) if dist_coeffs is None else np.asarray(dist_coeffs, float)
            ok, rvec, tvec = cv2.solvePnP(obj, img, np.asarray(camera_matrix, float), dist, flags=cv2.SOLVEPNP_IPPE)
            if not ok:
                raise ValueError("solvePnP failed: cannot recover the camera pose from these clicks")
            rvec, tvec = rvec.ravel(), tvec.ravel()
        return cls(
            homography=h / h[2, 2],
            image_size=(int(image_size[0]), int(image_size[1])),
            image_points_px=img,
            court_points_m=court,
            point_names=list(names or []),
            camera_matrix=None if camera_matrix is None else np.asarray(camera_matrix, float),
            dist_coeffs=None if dist_coeffs is None else np.asarray(dist_coeffs, float).ravel(),
            rvec=rvec,
            tvec=tvec,
        )

    @staticmethod
    def _undistort(points_px: np.ndarray, k: np.ndarray | None, dist: np.ndarray | None) -> np.ndarray:
        if k is None or dist is None or not np.any(dist):
            return points_px
        return cv2.undistortPoints(points_px.reshape(-1, 1, 2), k, dist, P=k).reshape(-1, 2)

    # ------------------------------------------------------------------ mapping
    def court_to_image(self, points_m: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of ground points (N, 2) m (undistorted image)."""
        return _apply_homography(self.homography, points_m)

    def image_to_court(self, points_px: np.ndarray) -> np.ndarray:
        """Court ground coordinates (N, 2) m of pixels (N, 2) (removes lens distortion when known)."""
        pts = self._undistort(np.asarray(points_px, float).reshape(-1, 2), self.camera_matrix, self.dist_coeffs)
        return _apply_homography(np.linalg.inv(self.homography), pts)

    # ------------------------------------------------------------------ quality
    def reprojection_errors_px(self) -> np.ndarray:
        """Per-click distance (N,) px between the click and its court point mapped into the image."""
        undist = self._undistort(self.image_points_px, self.camera_matrix, self.dist_coeffs)
        return np.linalg.norm(self.court_to_image(self.court_points_m) - undist, axis=1)

    def court_errors_m(self) -> np.ndarray:
        """Per-click distance (N,) m between the click mapped onto the court and the true court point."""
        return np.linalg.norm(self.image_to_court(self.image_points_px) - self.court_points_m, axis=1)

    def summary(self) -> dict[str, float]:
        """RMS and max reprojection error, in pixels and in court metres."""
        px, m = self.reprojection_errors_px(), self.court_errors_m()
        return {
            "rms_px": float(np.sqrt(np.mean(px**2))),
            "max_px": float(px.max()),
            "rms_m": float(np.sqrt(np.mean(m**2))),
            "max_m": float(m.max()),
        }

    # ------------------------------------------------------------------ camera pose
    @property
    def has_pose(self) -> bool:
        return self.rvec is not None and self.camera_matrix is not None

    def camera_position_m(self) -> np.ndarray:
        """Camera centre (3,) in the court frame; needs intrinsics."""
        if not self.has_pose:
            raise ValueError("camera pose unknown: fit with camera_matrix to get it")
        rot, _ = cv2.Rodrigues(self.rvec)
        return -rot.T @ self.tvec

    def image_down_directions(self, points_px: np.ndarray) -> np.ndarray:
        """Unit image vectors (N, 2) along which a vertical body at each pixel points from head to feet.

        With a pose: the image step from a point 1 m above the ground under the pixel down to the ground point.
        Without: image-down ``(0, 1)`` (valid only for a camera whose image-down is towards its nadir)."""
        pts = np.asarray(points_px, float).reshape(-1, 2)
        if not self.has_pose:
            return np.tile([0.0, 1.0], (len(pts), 1))
        ground = self.image_to_court(pts)
        up = np.column_stack([ground, np.ones(len(pts))])
        up_px, _ = cv2.projectPoints(up, self.rvec, self.tvec, self.camera_matrix, None)
        step = self.court_to_image(ground) - up_px.reshape(-1, 2)
        return step / np.linalg.norm(step, axis=1, keepdims=True)

    # ------------------------------------------------------------------ persistence
    def to_dict(self) -> dict[str, Any]:
        def arr(a: np.ndarray | None) -> list | None:
            return None if a is None else np.asarray(a).tolist()

        return {
            "schema": SCHEMA,
            "schema_version": SCHEMA_VERSION,
            "homography": arr(self.homography),
            "image_size": list(self.image_size),
            "image_points_px": arr(self.image_points_px),
            "court_points_m": arr(self.court_points_m),
            "point_names": list(self.point_names),
            "camera_matrix": arr(self.camera_matrix),
            "dist_coeffs": arr(self.dist_coeffs),
            "rvec": arr(self.rvec),
            "tvec": arr(self.tvec),
            "errors": self.summary(),
        }

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=2))

    @classmethod
    def load(cls, path: str | Path) -> "CourtCalibration":
        """Read a saved calibration; CourtCalibrationFileError names the file and what is wrong."""
        path = Path(path)
        data = read_versioned_json(path, SCHEMA, SCHEMA_VERSION, "a court calibration", CourtCalibrationFileError)

        def matrix(key: str, shape: tuple[int, ...], optional: bool = False) -> np.ndarray | None:
            value = data.get(key)
            if value is None and optional:
                return None
            try:
                out = np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                raise CourtCalibrationFileError(path, f"{key!r} is not numeric") from None
            if out.ndim != len(shape) or any(s not in (-1, o) for s, o in zip(shape, out.shape)):
                raise CourtCalibrationFileError(path, f"{key!r} has shape {out.shape}, expected {shape}")
            if not np.all(np.isfinite(out)):
                raise CourtCalibrationFileError(path, f"{key!r} contains non-finite values")
            return out

        h = matrix("homography", (3, 3))
        if abs(np.linalg.det(h)) < 1e-12:
            raise CourtCalibrationFileError(path, "homography is singular")
        img, court = matrix("image_points_px", (-1, 2)), matrix("court_points_m", (-1, 2))
        if len(img) != len(court):
            raise CourtCalibrationFileError(path, "image_points_px and court_points_m differ in length")
        size = data.get("image_size")
        if not (isinstance(size, list) and len(size) == 2 and all(isinstance(v, int) and v > 0 for v in size)):
            raise CourtCalibrationFileError(path, f"image_size must be [width, height] in pixels, got {size!r}")
        return cls(
            homography=h,
            image_size=(size[0], size[1]),
            image_points_px=img,
            court_points_m=court,
            point_names=list(data.get("point_names") or []),
            camera_matrix=matrix("camera_matrix", (3, 3), optional=True),
            dist_coeffs=matrix("dist_coeffs", (-1,), optional=True),
            rvec=matrix("rvec", (3,), optional=True),
            tvec=matrix("tvec", (3,), optional=True),
        )
