"""The moderngl view draws the skeleton where the camera maths says it is (real EGL rendering, pixel checks)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from gui.render.camera import CameraMode, OrbitCamera, look_at, perspective, project_to_pixels
from gui.render.skeleton_renderer import ESTIMATE_STYLE, TRUTH_STYLE, bone_segments

# a stick figure standing near the near baseline (world frame: Y up, metres)
ROOT = np.array([1.5, 0.0, -10.0])
OFFSETS = np.array([[0, 1.0, 0], [0, 1.5, 0], [0, 1.75, 0], [0.2, 0.5, 0], [-0.2, 0.5, 0], [0.2, 0.0, 0],
                    [-0.2, 0.0, 0], [0.45, 1.4, 0], [-0.45, 1.4, 0]])
PARENTS = np.array([-1, 0, 1, 0, 0, 3, 4, 1, 1])
POSE = ROOT + OFFSETS


def is_estimate_colour(img: np.ndarray) -> np.ndarray:
    """Orange: strong red, little blue (the court, lines, sky and truth skeleton all fail this)."""
    r, g, b = (img[..., k].astype(int) for k in range(3))
    return (r > 100) & (b < 80) & (r - g > 30)


def is_truth_colour(img: np.ndarray) -> np.ndarray:
    r, g, b = (img[..., k].astype(int) for k in range(3))
    return (g > 100) & (b > 100) & (r < 90)


def test_projection_matches_hand_computed_pinhole():
    """A point straight ahead of the eye projects to the image centre; one at 45 deg half-fov hits the edge."""
    view = look_at(np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, -1.0]))
    vp = perspective(math.radians(90.0), 2.0, 0.1, 100.0) @ view
    px = project_to_pixels(np.array([[0.0, 0.0, -5.0], [0.0, 5.0, -5.0], [10.0, 0.0, -5.0]]), vp, 200, 100)
    np.testing.assert_allclose(px, [[100, 50], [100, 0], [200, 50]], atol=1e-9)


def test_bone_segments_drop_zero_length_bones():
    pos = np.array([[0, 0, 0], [0, 0, 0], [0, 1, 0]], float)
    a, b, segment = bone_segments(pos, np.array([-1, 0, 1]))
    np.testing.assert_allclose(a, [[0, 0, 0]])
    np.testing.assert_allclose(b, [[0, 1, 0]])
    np.testing.assert_array_equal(segment, [1])


@pytest.mark.parametrize("mode", [CameraMode.FOLLOW, CameraMode.STATIC])
def test_joints_render_at_their_projected_pixels(renderer, mode):
    cam = OrbitCamera()
    cam.set_mode(mode)
    if mode is CameraMode.FOLLOW:
        cam.snap_to(ROOT)
    img = renderer.render(cam, [(POSE, PARENTS, ESTIMATE_STYLE)])
    w, h = renderer.size
    assert img.shape == (h, w, 4)
    px = project_to_pixels(POSE, cam.view_proj(w / h), w, h)
    mask = is_estimate_colour(img)
    # every joint centre is drawn in skeleton colour (allow a 1-pixel neighbourhood for rasterisation)
    for col, row in np.round(px).astype(int):
        assert mask[row - 1:row + 2, col - 1:col + 2].any(), (col, row)
    # and the skeleton-coloured pixels stay within the projected joints' box (plus the joint radius)
    rows, cols = np.nonzero(mask)
    margin = 25 if mode is CameraMode.FOLLOW else 6
    assert cols.min() >= px[:, 0].min() - margin and cols.max() <= px[:, 0].max() + margin
    assert rows.min() >= px[:, 1].min() - margin and rows.max() <= px[:, 1].max() + margin
    assert mask.sum() > 30


def test_moving_the_player_moves_the_pixels(renderer):
    """Static camera: shifting the player 3 m along +X shifts the drawn figure to the right on screen."""
    cam = OrbitCamera()
    cam.set_mode(CameraMode.STATIC)
    cols_at = []
    for dx in (0.0, 3.0):
        img = renderer.render(cam, [(POSE + [dx, 0, 0], PARENTS, ESTIMATE_STYLE)])
        cols_at.append(np.nonzero(is_estimate_colour(img))[1].mean())
    w, h = renderer.size
    expected = project_to_pixels(ROOT + [[0, 1, 0], [3, 1, 0]], cam.view_proj(w / h), w, h)[:, 0]
    assert cols_at[1] - cols_at[0] == pytest.approx(expected[1] - expected[0], abs=3.0)


def test_truth_skeleton_drawn_beside_estimate_and_court_lines_visible(renderer):
    cam = OrbitCamera()
    cam.snap_to(ROOT)
    truth = POSE + [1.2, 0, 0]
    img = renderer.render(cam, [(POSE, PARENTS, ESTIMATE_STYLE), (truth, PARENTS, TRUTH_STYLE)])
    w, h = renderer.size
    head_est, head_truth = project_to_pixels(np.array([POSE[2], truth[2]]), cam.view_proj(w / h), w, h).round().astype(int)
    assert is_estimate_colour(img)[head_est[1] - 1:head_est[1] + 2, head_est[0] - 1:head_est[0] + 2].any()
    assert is_truth_colour(img)[head_truth[1] - 1:head_truth[1] + 2, head_truth[0] - 1:head_truth[0] + 2].any()
    # the near baseline (court y = -11.885 m) is white where it projects, away from the players
    on_line = project_to_pixels(np.array([[ROOT[0] - 1.0, 0.0, -11.885]]), cam.view_proj(w / h), w, h).round().astype(int)[0]
    assert 1 <= on_line[0] < w - 1 and 1 <= on_line[1] < h - 1
    patch = img[on_line[1] - 1:on_line[1] + 2, on_line[0] - 1:on_line[0] + 2, :3]
    assert (patch.min(axis=-1) > 180).any()


@pytest.mark.parametrize("samples", [0, 4])
def test_resize_keeps_rendering(samples):
    """Resizing reallocates the framebuffers (with and without MSAA) and the next frame has the new size."""
    from gui.render.skeleton_renderer import SkeletonRenderer

    r = SkeletonRenderer(64, 48, samples=samples)
    try:
        cam = OrbitCamera()
        cam.snap_to(ROOT)
        for size in ((120, 80), (200, 100)):
            r.resize(*size)
            img = r.render(cam, [(POSE, PARENTS, ESTIMATE_STYLE)])
            assert img.shape == (size[1], size[0], 4)
            assert is_estimate_colour(img).any()
    finally:
        r.release()


def test_skeleton_view_widget_renders_and_orbits(qtbot):
    """The Qt pane blits the renderer's frame; the truth figure is offset beside the estimate; wheel/drag move
    the camera; static mode frames the court."""
    from PySide6 import QtCore, QtGui

    from gui.widgets.skeleton_view import SkeletonView

    view = SkeletonView()
    qtbot.addWidget(view)
    view.resize(480, 320)
    view.show()
    view.set_skeleton(PARENTS)
    view.set_poses(POSE, POSE)
    assert view.refresh()
    img = view.last_pixels()
    assert is_estimate_colour(img).sum() > 30 and is_truth_colour(img).sum() > 30
    assert not view.refresh()  # nothing changed: no re-render
    d0 = view.camera.distance_m
    wheel = QtGui.QWheelEvent(QtCore.QPointF(10, 10), QtCore.QPointF(10, 10), QtCore.QPoint(0, 0),
                              QtCore.QPoint(0, 120), QtCore.Qt.NoButton, QtCore.Qt.NoModifier,
                              QtCore.Qt.NoScrollPhase, False)
    view.wheelEvent(wheel)
    assert view.camera.distance_m < d0
    yaw0 = view.camera.yaw_rad
    qtbot.mousePress(view, QtCore.Qt.LeftButton, pos=QtCore.QPoint(100, 100))
    qtbot.mouseMove(view, QtCore.QPoint(160, 100))
    qtbot.mouseRelease(view, QtCore.Qt.LeftButton, pos=QtCore.QPoint(160, 100))
    assert view.camera.yaw_rad != yaw0
    view.set_camera_mode(CameraMode.STATIC)
    assert view.mode_box.currentText() == "static" and view.refresh()


def test_segment_colour_paints_that_segments_bones(renderer):
    """A sensor-health colour on joint 3 (left thigh: 3 -> 5) turns that bone red and nothing else."""
    from dataclasses import replace

    cam = OrbitCamera()
    cam.snap_to(ROOT)
    style = replace(ESTIMATE_STYLE, segment_rgb={3: (0.9, 0.1, 0.1)})
    img = renderer.render(cam, [(POSE, PARENTS, style)])
    w, h = renderer.size
    px = project_to_pixels(POSE, cam.view_proj(w / h), w, h)
    r, g, b = (img[..., k].astype(int) for k in range(3))
    red = (r > 100) & (g < 60) & (b < 60)
    mid_thigh = np.round((px[3] + px[5]) / 2).astype(int)
    mid_spine = np.round((px[0] + px[1]) / 2).astype(int)
    assert red[mid_thigh[1] - 1:mid_thigh[1] + 2, mid_thigh[0] - 1:mid_thigh[0] + 2].any()
    assert not red[mid_spine[1] - 2:mid_spine[1] + 3, mid_spine[0] - 2:mid_spine[0] + 3].any()
    assert is_estimate_colour(img)[mid_spine[1] - 1:mid_spine[1] + 2, mid_spine[0] - 1:mid_spine[0] + 2].any()


def test_the_views_right_is_the_screens_right():
    """The ground truth is drawn `right_m` of the estimate: that must be to the right on screen at any yaw."""
    cam = OrbitCamera()
    for yaw in (-2.0, -0.5, 0.0, 0.7, 2.5):
        cam.yaw_rad = yaw
        cam.snap_to(ROOT)
        vp = cam.view_proj(1.5)
        (left, _), (right, _) = project_to_pixels(np.array([ROOT, ROOT + cam.right_m()]), vp, 300, 200)
        assert right > left + 5
