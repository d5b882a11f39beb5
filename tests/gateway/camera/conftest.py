"""Fixtures: the default synthetic camera and a court calibration fitted from realistic (noisy) clicks."""
from __future__ import annotations

import numpy as np
import pytest

from gateway.camera import COURT_KEYPOINTS_M, CourtCalibration, default_court_camera

CLICK_NOISE_PX = 0.5


@pytest.fixture(scope="session")
def court_camera():
    return default_court_camera()


def clicked_points(camera, names, noise_px: float, seed: int = 0) -> np.ndarray:
    """Where an operator would click the named keypoints: true projection plus click noise (px)."""
    court = np.array([COURT_KEYPOINTS_M[n] for n in names])
    true_px = camera.project(np.column_stack([court, np.zeros(len(court))]))
    return true_px + np.random.default_rng(seed).normal(0.0, noise_px, true_px.shape)


@pytest.fixture(scope="session")
def calibration(court_camera) -> CourtCalibration:
    """Fitted from all 16 keypoints clicked with 0.5 px noise, with the camera's intrinsics (pose known)."""
    names = list(COURT_KEYPOINTS_M)
    return CourtCalibration.fit(
        clicked_points(court_camera, names, CLICK_NOISE_PX), names=names,
        image_size=court_camera.image_size, camera_matrix=court_camera.camera_matrix,
    )
