"""Ideal pinhole camera looking at the court plane: projection and the ground-plane homography.

Why: the synthetic court camera needs a *known* camera so its homography (and the parallax of a standing player)
is exact ground truth, and the tracker needs the camera centre to correct the parallax of the blob centroid.
Convention: ``x_cam = R @ x_court + t`` (OpenCV: x right, y down, z forward), pixels ``(u, v)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PinholeCamera:
    """Intrinsics ``camera_matrix`` (3, 3) px, extrinsics ``rotation`` (3, 3) and ``translation_m`` (3,)."""

    camera_matrix: np.ndarray
    rotation: np.ndarray
    translation_m: np.ndarray
    image_size: tuple[int, int]  # (width_px, height_px)

    @classmethod
    def look_at(
        cls,
        position_m: tuple[float, float, float],
        target_m: tuple[float, float, float],
        focal_px: float,
        image_size: tuple[int, int],
        image_up_hint: tuple[float, float, float] = (0.0, 1.0, 0.0),
    ) -> "PinholeCamera":
        """Camera at ``position_m`` (court frame) aimed at ``target_m``; ``image_up_hint`` is the court direction
        that should point up in the image (it must not be parallel to the viewing direction)."""
        pos = np.asarray(position_m, float)
        forward = np.asarray(target_m, float) - pos
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(image_up_hint, float))
        norm = np.linalg.norm(right)
        if norm < 1e-9:
            raise ValueError("image_up_hint is parallel to the viewing direction")
        right /= norm
        down = np.cross(forward, right)
        rotation = np.stack([right, down, forward])  # rows: camera axes in court coordinates
        width, height = image_size
        k = np.array([[focal_px, 0.0, (width - 1) / 2.0], [0.0, focal_px, (height - 1) / 2.0], [0.0, 0.0, 1.0]])
        return cls(k, rotation, -rotation @ pos, (int(width), int(height)))

    @property
    def position_m(self) -> np.ndarray:
        """Camera centre in the court frame (m)."""
        return -self.rotation.T @ self.translation_m

    def project(self, points_m: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of court points (N, 3) m. Points must be in front of the camera."""
        cam = np.asarray(points_m, float) @ self.rotation.T + self.translation_m
        uvw = cam @ self.camera_matrix.T
        return uvw[:, :2] / uvw[:, 2:3]

    def ground_homography(self) -> np.ndarray:
        """H (3, 3) with ``H @ [x, y, 1] ~ [u, v, 1]`` for ground points (z = 0): ``K [r1 r2 t]``."""
        h = self.camera_matrix @ np.column_stack([self.rotation[:, 0], self.rotation[:, 1], self.translation_m])
        return h / h[2, 2]
