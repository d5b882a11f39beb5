"""Health rules (sync colour, alarms) on exact status dicts, and the panels that show them."""
from __future__ import annotations

import numpy as np
import pytest

from gui.health import Sync, sensor_sync, status_alarms, sync_reason, sync_status
from gui.widgets.alarms import AlarmBar
from gui.widgets.camera_pane import CourtMinimap, apply_homography
from gui.widgets.device_panel import DevicePanel, segment_for


def station(name="st1", link="streaming", residual=0.002, locked=True, battery=95, last=10.0, loss=0.0):
    return {"station": name, "link": link, "crc_errors": 0,
            "clock": {"offset_s": 1.0, "skew_ppm": 10.0, "residual_s": residual, "locked": locked},
            "sensors": [{"sensor": 0, "nominal_hz": 100, "rate_hz": 100.0, "loss_pct": loss, "lost": 0,
                         "battery_pct": battery, "rssi_dbm": -50, "last_t_host_s": last}]}


def test_sync_traffic_light():
    assert sync_status(station(residual=0.002)) is Sync.GREEN
    assert sync_status(station(residual=0.010)) is Sync.AMBER
    assert sync_status(station(locked=False)) is Sync.AMBER
    assert sync_status(station(residual=0.050)) is Sync.RED
    assert sync_status(station(link="stale")) is Sync.RED


def test_the_sync_light_says_why_in_words():
    """Issue 30: the cell said "green" on green; now it says what the colour means."""
    assert sync_reason(station(residual=0.002)) == "locked"
    assert sync_reason(station(residual=0.0123)) == "residual 12.3 ms"
    assert sync_reason(station(locked=False)) == "warming up"
    assert sync_reason(station(link="lost")) == "link lost"
    lossy = station(loss=7.5)
    assert sensor_sync(lossy, lossy["sensors"][0]) == (Sync.RED, "loss 7.5 %")


def test_alarms_sensor_lost_sync_lost_battery_disk(tmp_path):
    was_locked: set[str] = set()
    ok = {"t_host_s": 10.2, "stations": [station()]}
    assert status_alarms(ok, str(tmp_path), was_locked) == []
    assert was_locked == {"st1"}
    bad = {"t_host_s": 12.0, "stations": [station(locked=False, battery=12, last=10.0)]}
    keys = {a.key for a in status_alarms(bad, None, was_locked)}
    assert keys == {"sync:st1", "battery:st1/0", "lost:st1/0"}
    # a station still warming up (never locked) is not "sync lost"
    assert not [a for a in status_alarms({"t_host_s": 1, "stations": [station("st2", locked=False, last=1)]},
                                         None, set()) if a.key.startswith("sync")]


def test_camera_health_from_the_gateway_raises_alarms():
    def camera(**kw):
        return {"t_host_s": 1.0, "stations": [], "camera": {"state": "running", "fps": 29.5, "nominal_fps": 30.0,
                                                            "frames": 100, "error": None, **kw}}
    assert status_alarms(camera(), None) == []
    assert [a.level for a in status_alarms(camera(state="failed", error="USB gone"), None)] == ["alarm"]
    assert "USB gone" in status_alarms(camera(state="failed", error="USB gone"), None)[0].message
    assert [a.level for a in status_alarms(camera(fps=9.0), None)] == ["warning"]
    assert status_alarms(camera(fps=9.0, frames=5), None) == []  # too early to judge the rate


def test_alarm_bar_shows_clears_and_dismisses(qtbot):
    from gui.health import Alarm

    bar = AlarmBar()
    qtbot.addWidget(bar)
    a, b = Alarm("lost:st1/0", "alarm", "sensor st1/0: no data"), Alarm("disk", "warning", "low disk")
    bar.set_conditions([a, b])
    assert set(bar.active()) == {"lost:st1/0", "disk"}
    bar._dismiss("disk")
    bar.set_conditions([a, b])
    assert set(bar.active()) == {"lost:st1/0"}   # acknowledged: stays hidden while the condition lasts
    bar.set_conditions([])
    assert bar.active() == {}                   # cleared conditions disappear by themselves
    bar.set_conditions([b])
    assert set(bar.active()) == {"disk"}        # and come back if the condition returns
    bar.add_event("warning", "st1", "reconnected")
    assert "event:st1:reconnected" in bar.active()


def test_device_panel_rows_and_renamed_station(qtbot):
    panel = DevicePanel()
    qtbot.addWidget(panel)
    panel.set_mapping({("st1", 0): "left_wrist"})
    panel.update_status({"t_host_s": 1.0, "stations": [{"station": "/dev/pts/3", "link": "connecting", "sensors": []}]})
    panel.update_status({"t_host_s": 2.0, "stations": [station()]})
    assert ("station", "/dev/pts/3") not in panel._items and panel.tree.topLevelItemCount() == 1
    row = panel.row_texts(("sensor", "st1", 0))
    assert row[1] == "streaming" and row[2] == "95" and row[11] == "locked" and row[12] == "left_wrist"
    assert panel.body.segment_state["left_forearm"] == ("st1/0", Sync.GREEN)
    station_row = panel.row_texts(("station", "st1"))
    assert station_row[8] == "+1.000" and "power-on" in panel._items[("station", "st1")].toolTip(8)
    button = panel.identify_button("st1", 0)
    assert button.width() <= button.sizeHint().width() + 4  # not stretched over the rest of the row


def test_device_panel_draws_one_body_diagram_per_athlete(qtbot):
    panel = DevicePanel()
    qtbot.addWidget(panel)
    panel.resize(1200, 300)
    panel.show()
    panel.set_mapping({("st1", 0): "left_wrist", ("st2", 0): "left_wrist"})
    panel.sensor_athletes = {("st1", 0): "alice", ("st2", 0): "bob"}
    panel.update_status({"t_host_s": 2.0, "stations": [station("st1"), station("st2")]})
    assert list(panel.bodies) == ["alice", "bob"] and [b.title for b in panel.bodies.values()] == ["alice", "bob"]
    assert panel.bodies["bob"].segment_state["left_forearm"] == ("st2/0", Sync.GREEN)
    panel.sensor_athletes = {}  # one athlete wearing both: forearm and wrist share a segment, both are named
    panel.update_status({"t_host_s": 3.0, "stations": [station("st1"), station("st2", loss=9.0)]})
    assert panel.bodies[""].segment_state["left_forearm"] == ("st1/0, st2/0", Sync.RED)


def test_segment_names_map_to_the_body_diagram():
    assert segment_for("left_wrist") == "left_forearm"
    assert segment_for("right_shin") == "right_shin"
    assert segment_for("lower_back") == "pelvis"
    assert segment_for("right_foot") == "right_shin"
    assert segment_for("chest") == "chest"


def test_minimap_and_homography(qapp):  # a widget needs the QApplication, whichever test ran first
    h = np.array([[2.0, 0, 10], [0, -2.0, 20], [0, 0, 1]])
    np.testing.assert_allclose(apply_homography(h, np.array([[1.0, 1.0]])), [[12.0, 18.0]])
    m = CourtMinimap()
    m.resize(200, 400)
    t = m.court_to_widget()
    far = t.map(0.0, 11.885)
    near = t.map(0.0, -11.885)
    assert far[1] < near[1]  # far baseline drawn at the top


def test_camera_pane_overlays_court_and_player_where_the_homography_says(qtbot):
    import cv2
    from PySide6 import QtGui

    from gui.widgets.camera_pane import CameraPane

    # a 400x300 black frame; homography: court metres -> pixels, 10 px/m, court centre at (200, 150), y up
    h = np.array([[10.0, 0, 200], [0, -10.0, 150], [0, 0, 1]])
    ok, jpeg = cv2.imencode(".jpg", np.zeros((300, 400, 3), np.uint8))
    pane = CameraPane()
    qtbot.addWidget(pane)
    pane.view.setFixedSize(400, 300)  # 1:1 with the frame, so frame pixels are widget pixels
    pane.resize(700, 320)
    pane.show()
    header = {"t_host_s": 5.0, "frame_index": 8, "position_m": [2.0, -8.0], "heading_rad": 0.0, "confidence": 0.9,
              "court_to_image": h.tolist()}
    trail = np.array([[4.0, 0.0, -8.0], [4.5, 1.0, -8.0], [5.0, 2.0, -8.0]])
    from gui.bridge import CameraRate

    rate = CameraRate()
    pane.update_camera(header, jpeg.tobytes(), trail, rate)
    qtbot.wait(50)
    img = pane.view.grab().toImage().convertToFormat(QtGui.QImage.Format_RGB888)
    px = np.frombuffer(img.constBits(), np.uint8).reshape(img.height(), img.bytesPerLine())[:, :3 * img.width()]
    px = px.reshape(img.height(), img.width(), 3).astype(int)
    # near baseline corner (-5.485, -11.885) m -> (145, 269) px: court-line colour (cyan: low red, high blue)
    col, row = apply_homography(h, np.array([[-5.485 + 2.0, -11.885]]))[0].round().astype(int)
    patch = px[row - 1:row + 2, col - 1:col + 2]
    assert ((patch[..., 2] > 150) & (patch[..., 0] < 120)).any()
    # the player marker (orange) sits at the projected position (220, 230) px
    col, row = apply_homography(h, np.array([[2.0, -8.0]]))[0].round().astype(int)
    ring = px[row - 8:row + 9, col - 8:col + 9]
    assert ((ring[..., 0] > 200) & (ring[..., 2] < 100)).any()
    np.testing.assert_allclose(pane.minimap.trail_m, trail[:, 1:])
    assert "+2.00, -8.00" in pane.info.text()
    for k in [i for i in range(8, 30) if i != 15]:  # 12 fps with frame 15 dropped
        rate.add(5.0 + (k - 8) / 12.0, k)
    pane.update_camera(dict(header, frame_index=29), None, trail, rate)
    assert rate.dropped == 1 and rate.fps == pytest.approx(12.0, rel=0.05)
    assert "12.0 fps, 1 dropped" in pane.info.text()


def test_unhealthy_worn_sensors_colour_their_segments():
    from gui.main_window import HEALTH_RGB, segment_health_colours

    joints = {("st1", 0): 12, ("st1", 1): 20, ("st1", 2): 3}
    health = {("st1", 0): Sync.GREEN, ("st1", 1): Sync.RED, ("st1", 2): Sync.AMBER}
    assert segment_health_colours(joints, health) == {20: HEALTH_RGB[Sync.RED], 3: HEALTH_RGB[Sync.AMBER]}
    assert segment_health_colours(joints, {}) == {}


def test_sensor_joints_follow_standard_placements():
    from engine.mocap import load_clip, sample_clips, standard_placements
    from gui.engine_link import sensor_joints

    skeleton = load_clip(sample_clips()["16_01"]).skeleton
    worn = {("st1", 0): "left_forearm", ("st1", 1): "chest"}
    expected = [p.joint for p in standard_placements(skeleton, ("left_forearm", "chest"))]
    assert sensor_joints(skeleton, worn) == {("st1", 0): expected[0], ("st1", 1): expected[1]}
    assert skeleton.names[expected[0]].startswith("l")  # a left-arm joint


def test_camera_rate_survives_a_source_that_starts_its_frame_index_again():
    """A looping court video (`[camera] loop = true`) starts its frame index at 0 again: the console showed
    "camera -22.3 fps"; the rate stays the frame rate and no frames count as dropped."""
    from gui.bridge import CameraRate

    rate = CameraRate()
    t = 100.0 + np.arange(60) / 15.0
    for k, tk in enumerate(t):
        rate.add(float(tk), k % 20)  # the file has 20 frames: the index wraps at 20 and 40
    assert rate.fps == pytest.approx(15.0) and rate.dropped == 0
