"""Live traces: samples put from a network-side thread reach the plotted curves (real widgets, offscreen)."""
from __future__ import annotations

import threading

import numpy as np

from gui.ringbuffer import TraceStore
from gui.widgets.traces import TracePanel

RATE_HZ = 100.0


def known_signal(t: np.ndarray, k: int) -> np.ndarray:
    """Sensor k: x = sin(2 pi (k+1) t), y = 0.5, z = -1 (g) — exact values to check the plotted data against."""
    return np.c_[np.sin(2 * np.pi * (k + 1) * t), np.full(len(t), 0.5), np.full(len(t), -1.0)]


def feed(store: TraceStore, sensors: list[str], seconds: float) -> None:
    """Push 10-sample batches for every sensor, as the gateway client's reader thread does."""
    n = int(seconds * RATE_HZ)
    for start in range(0, n, 10):
        t = np.arange(start, start + 10) / RATE_HZ
        for k, s in enumerate(sensors):
            store.put(s, t, known_signal(t, k))


def shown_panel(qtbot, groups: dict[str, list[str]]) -> tuple[TraceStore, TracePanel]:
    """A 5 s window panel on screen (offscreen Qt, 800x600) over a 30 s store, showing `groups`' first group."""
    store = TraceStore(history_s=30.0)
    panel = TracePanel(store, window_s=5.0)
    qtbot.addWidget(panel)
    panel.resize(800, 600)
    panel.show()
    panel.set_groups(groups)
    return store, panel


def test_traces_receive_data_from_another_thread(qtbot):
    sensors = [f"st1/s{k}" for k in range(6)]
    store, panel = shown_panel(qtbot, {"station 1": sensors})
    worker = threading.Thread(target=feed, args=(store, sensors, 12.0))
    worker.start()
    worker.join()
    store.put_event(11.0, "tap")
    assert store.drain() == 6 * 120 + 1
    panel.refresh()
    for k, s in enumerate(sensors):
        t, x = panel.curve_data(s, 0)
        # only the last 5 s window is drawn, newest sample last
        assert t[0] >= 12.0 - 0.01 - 5.0 - 1e-9 and t[-1] == 11.99
        np.testing.assert_allclose(x, np.sin(2 * np.pi * (k + 1) * t), atol=1e-12)
        _, mag = panel.curve_data(s, 3)
        np.testing.assert_allclose(mag, np.sqrt(x ** 2 + 0.25 + 1.0), atol=1e-12)
    assert [len(lines) for lines in panel._event_lines.values()] == [len(sensors)]  # one tap line per plot


def test_old_event_markers_are_dropped_with_the_history(qtbot):
    store = TraceStore(history_s=5.0)
    panel = TracePanel(store)
    qtbot.addWidget(panel)
    panel.set_groups({"a": ["s0", "s1"]})
    feed(store, ["s0", "s1"], 2.0)
    store.put_event(1.0, "early")
    store.drain()
    panel.refresh()
    assert len(panel._event_lines) == 1 and len(panel._plots["s0"].items) > 4
    t = np.arange(200, 800) / RATE_HZ   # 6 s later: the early event is older than the 5 s history
    store.put("s0", t, known_signal(t, 0))
    store.put_event(7.5, "late")
    store.drain()
    panel.refresh()
    assert [label for _, _, label in store.events] == ["late"]
    assert len(panel._event_lines) == 1
    lines = next(iter(panel._event_lines.values()))
    # the line sits at the event's time on the scrolling axis (seconds before the newest sample, 7.99 s)
    assert all(abs(line.value() - (7.5 - 7.99)) < 1e-12 for _, line in lines)
    assert all(line in plot.items for plot, line in lines)


def test_pause_freezes_curves_but_keeps_buffering(qtbot):
    store = TraceStore()
    panel = TracePanel(store, window_s=5.0)
    qtbot.addWidget(panel)
    panel.set_groups({"a": ["s0"]})
    feed(store, ["s0"], 2.0)
    store.drain()
    panel.refresh()
    frozen = panel.curve_data("s0", 0)[0].copy()
    panel.set_paused(True)
    t = np.arange(200, 300) / RATE_HZ
    store.put("s0", t, known_signal(t, 0))
    store.drain()
    panel.refresh()
    np.testing.assert_array_equal(panel.curve_data("s0", 0)[0], frozen)
    assert store.rings["s0"].latest_time() == 2.99
    panel.set_paused(False)
    panel.refresh()
    assert panel.curve_data("s0", 0)[0][-1] == 2.99


def test_range_presets_and_many_points_are_decimated(qtbot):
    store = TraceStore(history_s=30.0, nominal_rate_hz=1000.0)
    panel = TracePanel(store, window_s=30.0)
    qtbot.addWidget(panel)
    panel.resize(600, 300)
    panel.set_groups({"a": ["s0"]})
    t = np.arange(30_000) / 1000.0
    acc = np.zeros((len(t), 3))
    acc[12_345, 2] = 9.0  # one-sample spike must survive decimation
    store.put("s0", t, acc)
    store.drain()
    panel.refresh()
    td, z = panel.curve_data("s0", 2)
    assert len(td) <= 2 * max(200, panel.graphics.width())
    assert z.max() == 9.0
    panel.set_range_g(12.0)
    lo, hi = panel._plots["s0"].viewRange()[1]
    assert lo <= -12.0 and hi >= 12.0 and hi < 13.0


def test_a_sensor_silent_for_longer_than_the_window_clears_its_curve_and_the_others_keep_drawing(qtbot):
    """A sensor that stopped (battery, a gateway restarted without it) has no sample in the time window: its
    curve is empty, and the sensors after it in the panel still update (before: a ValueError traceback on every
    GUI tick from the empty slice, and the later sensors' curves froze)."""
    sensors = ["st1/s0", "st1/s1"]
    store = TraceStore(history_s=30.0)
    panel = TracePanel(store, window_s=5.0)
    qtbot.addWidget(panel)
    panel.set_groups({"station 1": sensors})
    t_old = np.arange(0, 100) / RATE_HZ  # s0: one second of data, 19 s before the newest sample
    store.put(sensors[0], t_old, known_signal(t_old, 0))
    t_new = np.arange(1900, 2000) / RATE_HZ
    store.put(sensors[1], t_new, known_signal(t_new, 1))
    store.drain()
    panel.refresh()
    assert len(panel.curve_data(sensors[0], 0)[0]) == 0
    t, x = panel.curve_data(sensors[1], 0)
    np.testing.assert_allclose(t, t_new)
    np.testing.assert_allclose(x, known_signal(t_new, 1)[:, 0])


def test_orientation_and_angular_rate_views(qtbot):
    """A sensor turning about the earth's vertical at 0.5 rad/s with a fixed 30 degree roll: the orientation view
    draws roll 30, pitch 0 and the yaw ramp; the rate view the rate; a sensor without them draws nothing."""
    store, panel = shown_panel(qtbot, {"station 1": ["imu", "acc-only"]})
    t = np.arange(0, 400) / RATE_HZ
    yaw, roll = 0.5 * t, np.radians(30.0)
    q_yaw = np.c_[np.cos(yaw / 2), np.zeros((len(t), 2)), np.sin(yaw / 2)]
    q_roll = np.array([np.cos(roll / 2), np.sin(roll / 2), 0.0, 0.0])
    w1, x1, y1, z1 = q_yaw.T  # q = q_yaw * q_roll (roll in the sensor, then the heading)
    w2, x2, y2, z2 = q_roll
    quat = np.c_[w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                 w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2]
    gyro = np.tile([0.0, 0.0, 0.5], (len(t), 1))
    for start in range(0, len(t), 10):
        sl = slice(start, start + 10)
        store.put("imu", t[sl], known_signal(t[sl], 0), quat[sl], gyro[sl])
        store.put("acc-only", t[sl], known_signal(t[sl], 1))
    store.drain()
    panel.set_view("orientation (deg)")
    panel.refresh()
    tt, r = panel.curve_data("imu", 0)
    np.testing.assert_allclose(r, 30.0, atol=1e-9)
    np.testing.assert_allclose(panel.curve_data("imu", 1)[1], 0.0, atol=1e-9)
    np.testing.assert_allclose(panel.curve_data("imu", 2)[1], np.degrees(0.5 * tt), atol=1e-9)  # < 180 deg here
    assert len(panel.curve_data("imu", 3)[1]) == 0 and len(panel.curve_data("acc-only", 0)[1]) == 0
    assert not panel.range_box.isEnabled()
    panel.set_view("angular rate (rad/s)")
    panel.refresh()
    np.testing.assert_allclose(panel.curve_data("imu", 2)[1], 0.5, atol=1e-12)
    np.testing.assert_allclose(panel.curve_data("imu", 3)[1], 0.5, atol=1e-12)
    panel.set_view("acceleration (g)")
    panel.refresh()
    assert len(panel.curve_data("acc-only", 0)[1]) > 100 and panel.range_box.isEnabled()


def test_the_view_stays_on_the_last_window_and_the_data_scroll(qtbot):
    """Oscilloscope scrolling: the x range is fixed at -window .. 0 s (before the newest sample) whatever the
    clock says, a new window size re-ranges it, and an event line sits at its time before the newest sample."""
    store, panel = shown_panel(qtbot, {"a": ["s0", "s1"]})
    qtbot.wait(100)   # the layout settles (linked views compare widths)
    feed(store, ["s0", "s1"], 8.0)
    store.put_event(6.5, "tap")
    store.drain()
    panel.refresh()
    for plot in panel._plots.values():
        lo, hi = plot.viewRange()[0]
        assert abs(lo + 5.0) < 1e-9 and abs(hi) < 1e-9
    curve = panel._curves["s0"][0]
    assert curve.xData[-1] == 0.0 and curve.xData[0] >= -5.0   # drawn relative to the newest sample (7.99 s)
    line = panel._event_lines[next(iter(panel._event_lines))][0][1]
    assert abs(line.value() - (6.5 - 7.99)) < 1e-12
    t = np.arange(800, 900) / RATE_HZ   # one more second: the data move, the view does not
    store.put("s0", t, known_signal(t, 0))
    store.drain()
    panel.refresh()
    assert abs(line.value() - (6.5 - 8.99)) < 1e-12
    assert panel._plots["s1"].viewRange()[0] == panel._plots["s0"].viewRange()[0]
    panel.window_box.setCurrentIndex(panel.window_box.findData(30.0))
    assert abs(panel._plots["s1"].viewRange()[0][0] + 30.0) < 1e-9
