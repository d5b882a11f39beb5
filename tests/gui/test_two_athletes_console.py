"""The console's two-athlete pieces (issue 20) with real widgets offscreen and real EGL: each skeleton is drawn
in its own colour at its court spot, camera fixes reach only their own athlete's synthesis, traces and the
device panel group sensors per athlete, and the minimap/overlay get both tracks."""
from __future__ import annotations

import numpy as np

from gateway.codec import Message
from gui.bridge import GatewayBridge
from gui.ringbuffer import TraceStore

from .test_skeleton_render import PARENTS, POSE, is_estimate_colour, is_truth_colour


def is_second_athlete_colour(img: np.ndarray) -> np.ndarray:
    """Green: strong green, little red and blue (court, lines, truth and the orange estimate fail this)."""
    r, g, b = (img[..., k].astype(int) for k in range(3))
    return (g > 150) & (r < 130) & (b < 130)


def test_each_athlete_drawn_at_its_court_spot_and_the_view_frames_both(qtbot):
    """Issue 30: the opponent stood 1.5 m beside the player while the minimap put it 21 m away. Each athlete is
    drawn over its camera track's spot (whatever its engine's own root), the follow view frames both, and an
    athlete without a track stands at its side's baseline, the legend saying so."""
    from gui.render.camera import project_to_pixels
    from gui.widgets.skeleton_view import SkeletonView

    view = SkeletonView()
    view.athlete = "alice"
    view.set_skeleton(PARENTS)
    view.resize(480, 320)
    qtbot.addWidget(view)
    view.show()
    view.set_poses(POSE, POSE)
    assert view.refresh() and is_second_athlete_colour(view.last_pixels()).sum() == 0
    engine_world = POSE + [30.0, 0.0, 40.0]  # an engine's root far off the court: the court decides
    view.set_other_athletes({"bob": (engine_world, None)})
    view.set_court_spots({"alice": np.array([2.0, -9.0]), "bob": np.array([-3.0, 9.0])})
    assert view.refresh()
    img = view.last_pixels()
    green, orange, cyan = is_second_athlete_colour(img), is_estimate_colour(img), is_truth_colour(img)
    assert green.sum() > 10 and orange.sum() > 10 and cyan.sum() > 10
    h, w = img.shape[:2]
    view_proj = view.camera.view_proj(w / h)
    for mask, (x, y) in ((green, (-3.0, 9.0)), (orange, (2.0, -9.0))):
        (col, row), = project_to_pixels(np.array([[x, 1.0, y]]), view_proj, w, h)  # the pelvis over the spot
        assert 0 <= col < w and 0 <= row < h  # in view: both athletes framed
        rows, cols = np.nonzero(mask)
        assert np.hypot(rows.mean() - row, cols.mean() - col) < 25, (rows.mean(), cols.mean(), row, col)
    assert "alice" in view.legend.text() and "bob" in view.legend.text() and "no camera" not in view.legend.text()
    assert "drawn 1.5 m beside the estimate" in view.legend.text()
    view.set_court_spots({"alice": np.array([2.0, -9.0]), "bob": None})  # bob's track gone: his side's spot
    assert "bob (no camera: at the far baseline)" in view.legend.text()
    view.set_other_athletes({"bob": (None, None)})  # no new pose: the last one stays
    assert "bob" in view.others


def test_athletes_without_a_camera_stand_at_their_sides_default_spots():
    from gui.render.placement import BASELINE_SPOT_FROM_NET_M, default_spot, place, track_spot

    assert default_spot("far", 0)[1] == BASELINE_SPOT_FROM_NET_M and default_spot("near", 1)[1] < 0
    assert default_spot(None, 0)[1] < 0 < default_spot(None, 1)[1]  # no sides: first near, second far
    placed = place(POSE + [0.0, 0.0, 40.0], np.array([1.0, 2.0]))
    np.testing.assert_allclose(placed[0], [1.0, POSE[0, 1], 2.0])
    np.testing.assert_allclose(placed - placed[0], POSE - POSE[0])
    trail = np.array([[0.0, 0.0, -10.0], [1.0, 2.0, -8.0]])
    np.testing.assert_allclose(track_spot(trail, 0.5), [1.0, -9.0])
    np.testing.assert_allclose(track_spot(trail, 5.0), [2.0, -8.0])  # after the newest fix: the last spot
    assert track_spot(np.zeros((0, 3)), 1.0) is None


def camera(athlete: str, t: float, frame: int, x: float, y: float) -> Message:
    return Message("camera", {"t_host_s": t, "frame_index": frame, "athlete": athlete, "position_m": [x, y],
                              "heading_rad": 0.0, "tracking": True}, {})


def test_camera_fixes_go_to_their_own_athlete_and_both_tracks_are_kept():
    bridge = GatewayBridge(TraceStore())
    got: dict[str, list] = {"alice": [], "bob": [], "any": []}
    bridge.athlete_camera_sinks = {name: [lambda t, p, h, n=name: got[n].append(p)] for name in ("alice", "bob")}
    bridge.camera_sinks.append(lambda t, p, h: got["any"].append(p))
    for k in range(5):
        bridge.on_camera(camera("alice", 0.1 * k, k, -1.0, -10.0 + k))
        bridge.on_camera(camera("bob", 0.1 * k, k, 2.0, 9.0 - k))
    assert got["alice"] == [[-1.0, -10.0 + k] for k in range(5)]
    assert got["bob"] == [[2.0, 9.0 - k] for k in range(5)]
    assert got["any"] == got["alice"]  # the one-athlete sinks see the first athlete only, once per frame
    tracks = bridge.athlete_tracks()
    assert set(tracks) == {"alice", "bob"} and tracks["bob"][1].shape == (5, 3) and tracks["bob"][1][-1, 2] == 5.0
    assert bridge.camera_athlete == "alice" and bridge.camera_frame()[2].shape == (5, 3)


def samples(station: str, sensor: int, athlete: str | None) -> Message:
    header = {"station": station, "sensor": sensor, "nominal_hz": 100.0}
    if athlete:
        header["athlete"] = athlete
    return Message("samples", header, {"t_host_s": np.array([1.0, 1.01]), "acc_g": np.zeros((2, 3), np.float32)})


def test_traces_and_device_panel_group_sensors_per_athlete(qtbot):
    from gui.widgets.camera_pane import CameraPane
    from gui.widgets.device_panel import DevicePanel

    bridge = GatewayBridge(TraceStore())
    for station, athlete in (("st2", "bob"), ("st1", "alice")):
        for i in range(2):
            bridge.on_samples(samples(station, i, athlete))
    assert list(bridge.sensor_groups()) == ["bob · station st2", "alice · station st1"]  # athletes as first seen
    single = GatewayBridge(TraceStore())
    single.on_samples(samples("st1", 0, "player"))
    assert list(single.sensor_groups()) == ["station st1"]  # one athlete: as before
    panel = DevicePanel()
    qtbot.addWidget(panel)
    panel.sensor_athletes = bridge.sensor_athletes
    panel.update_status({"stations": [{"station": s, "link": "streaming", "sensors": [{"sensor": 0}]}
                                      for s in ("st1", "st2")]})
    assert panel.row_texts(("station", "st1"))[0] == "station st1 · alice"
    assert panel.row_texts(("station", "st2"))[0] == "station st2 · bob"
    pane = CameraPane()
    qtbot.addWidget(pane)
    bridge.on_camera(camera("alice", 0.0, 0, -1.0, -10.0))
    bridge.on_camera(Message("camera", {"t_host_s": 0.0, "frame_index": 0, "athlete": "bob", "tracking": False,
                                        "status": "lost"}, {}))
    pane.update_athletes(bridge.athlete_tracks(), bridge.camera_athlete)
    assert pane.athletes_info.text() == "alice: (-1.0, -10.0) m  bob: LOST"
    assert len(pane.minimap.others) == 1 and pane.minimap.others[0][1] is None


def test_a_one_athlete_console_stands_its_athlete_on_the_cameras_track(qtbot):
    """The camera names its one athlete ("player") while the console names none: its track is still the spot."""
    from gui.main_window import ConsoleWindow

    window = ConsoleWindow()
    qtbot.addWidget(window)
    try:
        for k in range(3):
            window.bridge.on_camera(camera("player", float(k), k, 1.0 + k, -9.0))
        np.testing.assert_allclose(window._court_spots(1.5, {})[""], [2.5, -9.0])  # the pose's time, interpolated
    finally:
        window.shutdown()
