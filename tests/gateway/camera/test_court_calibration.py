"""Court model and homography calibration against a known pinhole camera."""
from __future__ import annotations

import json

import numpy as np
import pytest

from gateway.camera import COURT_KEYPOINTS_M, COURT_LINES_M, CourtCalibration, CourtCalibrationFileError
from gateway.camera.court import court_outline_m

from .conftest import clicked_points


def test_court_model_has_itf_dimensions():
    kp = COURT_KEYPOINTS_M
    assert len(kp) == 16
    assert kp["far_baseline_left_doubles"][1] - kp["near_baseline_left_doubles"][1] == pytest.approx(23.77)
    assert kp["near_baseline_right_doubles"][0] - kp["near_baseline_left_doubles"][0] == pytest.approx(10.97)
    assert kp["near_baseline_right_singles"][0] - kp["near_baseline_left_singles"][0] == pytest.approx(8.23)
    assert kp["far_service_centre"] == pytest.approx((0.0, 6.40))
    assert np.ptp(COURT_LINES_M["centre_service_line"][:, 1]) == pytest.approx(12.80)


def test_exact_clicks_recover_the_true_homography_and_pose(court_camera):
    names = list(COURT_KEYPOINTS_M)
    calib = CourtCalibration.fit(clicked_points(court_camera, names, 0.0), names=names,
                                 image_size=court_camera.image_size, camera_matrix=court_camera.camera_matrix)
    np.testing.assert_allclose(calib.homography, court_camera.ground_homography(), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(calib.camera_position_m(), court_camera.position_m, atol=1e-4)
    assert calib.summary()["max_m"] < 1e-6
    # a point that was never clicked maps correctly both ways
    probe_m = np.array([[2.5, -9.0], [-4.0, 3.3]])
    probe_px = court_camera.project(np.column_stack([probe_m, np.zeros(2)]))
    np.testing.assert_allclose(calib.image_to_court(probe_px), probe_m, atol=1e-6)
    np.testing.assert_allclose(calib.court_to_image(probe_m), probe_px, atol=1e-6)


def test_noisy_four_point_calibration_error_is_reported_in_pixels_and_metres(court_camera):
    names = ["near_baseline_left_doubles", "near_baseline_right_doubles", "far_baseline_right_doubles",
             "far_baseline_left_doubles"]
    calib = CourtCalibration.fit(clicked_points(court_camera, names, 1.0, seed=3), names=names,
                                 image_size=court_camera.image_size)
    # 4 points fit exactly: the residual is zero, so the check must use the other keypoints
    assert calib.summary()["rms_px"] < 1e-3
    others = [n for n in COURT_KEYPOINTS_M if n not in names]
    true_m = np.array([COURT_KEYPOINTS_M[n] for n in others])
    mapped = calib.image_to_court(clicked_points(court_camera, others, 0.0))
    assert 0.005 < np.sqrt(np.mean(np.sum((mapped - true_m) ** 2, axis=1))) < 0.15


def test_ransac_ignores_a_misclicked_point(court_camera):
    names = list(COURT_KEYPOINTS_M)
    clicks = clicked_points(court_camera, names, 0.3, seed=1)
    clicks[5] += (40.0, -25.0)  # operator clicked the wrong intersection
    plain = CourtCalibration.fit(clicks, names=names, image_size=court_camera.image_size)
    robust = CourtCalibration.fit(clicks, names=names, image_size=court_camera.image_size, ransac_threshold_px=3.0)
    assert plain.court_errors_m()[5] > 0.5  # the blunder is visible in the report
    good = np.delete(np.arange(len(names)), 5)
    assert np.sqrt(np.mean(robust.court_errors_m()[good] ** 2)) < 0.03
    assert np.sqrt(np.mean(plain.court_errors_m()[good] ** 2)) > 3 * np.sqrt(np.mean(robust.court_errors_m()[good] ** 2))


def test_bad_inputs_raise_clear_errors(court_camera):
    with pytest.raises(ValueError, match="at least 4"):
        CourtCalibration.fit(np.zeros((3, 2)), np.zeros((3, 2)), image_size=(10, 10))
    with pytest.raises(KeyError, match="unknown court keypoint 'net_post'"):
        CourtCalibration.fit(np.zeros((4, 2)), names=["net_post"] * 4, image_size=(10, 10))
    with pytest.raises(ValueError, match="image points but"):
        CourtCalibration.fit(np.zeros((5, 2)), np.zeros((4, 2)), image_size=(10, 10))


def test_save_load_round_trip(tmp_path, calibration):
    path = tmp_path / "court.json"
    calibration.save(path)
    loaded = CourtCalibration.load(path)
    np.testing.assert_allclose(loaded.homography, calibration.homography)
    np.testing.assert_allclose(loaded.camera_position_m(), calibration.camera_position_m())
    assert loaded.point_names == calibration.point_names
    assert loaded.summary() == pytest.approx(calibration.summary())
    outline = court_outline_m(1.0)
    np.testing.assert_allclose(loaded.court_to_image(outline), calibration.court_to_image(outline))


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        ("{not json", "not JSON"),
        ('{"schema": "something.else"}', "not a court calibration"),
        ("CORRUPT_H", "'homography' has shape"),
        ("SINGULAR_H", "singular"),
    ],
)
def test_load_rejects_bad_files_naming_file_and_problem(tmp_path, calibration, content, problem):
    path = tmp_path / "venue.json"
    data = calibration.to_dict()
    if content == "CORRUPT_H":
        data["homography"] = [[1, 0], [0, 1]]
        content = json.dumps(data)
    elif content == "SINGULAR_H":
        data["homography"] = [[1, 0, 0], [0, 0, 0], [0, 0, 1]]
        content = json.dumps(data)
    path.write_text(content)
    with pytest.raises(CourtCalibrationFileError, match=problem) as info:
        CourtCalibration.load(path)
    assert "venue.json" in str(info.value)


def test_missing_file_is_named(tmp_path):
    with pytest.raises(CourtCalibrationFileError, match="nope.json: cannot read"):
        CourtCalibration.load(tmp_path / "nope.json")
