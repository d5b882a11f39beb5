"""The emulated station core against its configuration: clocks, wrap, drift, determinism, faults, motion."""
from __future__ import annotations

import numpy as np
import pytest

from firmware_protocol import (
    ClockSync, Command, Hello, Opcode, SampleBatch, Status, StationFlags, StreamDecoder, encode,
)
from firmware_protocol.emulator import (
    BaseStation, Fate, MocapSource, StationConfig, StillSource, TraceSource,
)
from firmware_protocol.emulator.link import EmulatorLink

from .host import assert_matches_ground_truth


def _run(station: BaseStation, seconds: float, step_s: float = 0.25) -> list:
    decoder = StreamDecoder()
    frames = []
    for _ in range(round(seconds / step_s)):
        frames += decoder.feed(station.advance(step_s))
    return frames


def _unwrap_u32(ticks: np.ndarray) -> np.ndarray:
    """Host-side unwrap of a monotonic u32 counter sequence."""
    steps = np.diff(ticks.astype(np.int64))
    return ticks.astype(np.int64) + np.concatenate([[0], np.cumsum(steps < -(2**31))]) * 2**32


def test_output_is_independent_of_how_time_is_chunked():
    config = StationConfig(radio_loss=0.05, byte_corruption=0.002, burst_probability=0.05, noise_g=0.01,
                           jitter_s=0.004, seed=77)
    runs = []
    for steps in ([10.0], [0.1] * 100, [0.037] * 270 + [0.01]):
        station = BaseStation(config)
        out = station.advance(0.3)
        station.write(encode(Command(1, Opcode.START_STREAMING), 1, 0))
        out += b"".join(station.advance(dt) for dt in steps)
        runs.append(out)
    assert runs[0] == runs[1] == runs[2]
    assert len(runs[0]) > 20_000


def test_tick_wrap_is_visible_and_unwraps_to_the_true_clock():
    config = StationConfig(n_sensors=2, tick_offset=2**32 - 1_500_000, autostart=True, seed=2)
    station = BaseStation(config)
    frames = _run(station, 4.0)
    beacons = [f.message for f in frames if isinstance(f.message, ClockSync)]
    ticks = np.array([b.station_ticks for b in beacons])
    assert np.any(np.diff(ticks) < 0), "the u32 tick register should have wrapped"
    truth = station.truth.beacons()
    unwrapped = _unwrap_u32(ticks)
    np.testing.assert_array_equal(ticks, truth.ticks)
    np.testing.assert_allclose(np.diff(unwrapped), np.diff(truth.t_true_s) * 1e6, atol=1)
    batches = [f.message for f in frames if isinstance(f.message, SampleBatch) and f.message.sensor_id == 0]
    first = _unwrap_u32(np.array([b.first_sample_ticks for b in batches]))
    assert np.all(np.diff(first) == 50_000)                    # 5 samples x 10 000 ticks, straight across the wrap
    assert_matches_ground_truth(frames, station)              # sample ticks bit-exact across the wrap


@pytest.mark.parametrize("drift_ppm", [-80.0, 45.0])
def test_drift_matches_configuration(drift_ppm):
    """Sample latch ticks decoded from the wire vs the true sampling times: slope = tick rate x (1 + ppm)."""
    station = BaseStation(StationConfig(n_sensors=1, drift_ppm=drift_ppm, autostart=True, seed=4))
    frames = _run(station, 30.0, step_s=1.0)
    batches = [f.message for f in frames if isinstance(f.message, SampleBatch)]
    ticks = _unwrap_u32(np.array([b.first_sample_ticks for b in batches])).astype(float)
    truth = station.truth.samples()
    t_first = truth.t_true_s[np.isin(truth.counter, [b.first_sample_counter for b in batches])]
    slope = np.polyfit(t_first, ticks, 1)[0]
    assert slope / 1e6 - 1 == pytest.approx(drift_ppm * 1e-6, abs=0.02e-6)


def test_fractional_period_at_32768_hz():
    station = BaseStation(StationConfig(n_sensors=2, tick_rate_hz=32768, autostart=True, seed=1))
    frames = _run(station, 3.0)
    batches = [f.message for f in frames if isinstance(f.message, SampleBatch)]
    assert {b.period_ticks_q8 for b in batches} == {83886}      # 327.68 ticks in Q24.8
    truth = station.truth.samples()
    for b in batches:
        sel = (truth.sensor_id == b.sensor_id) & np.isin(truth.counter, b.first_sample_counter + np.arange(b.n_samples))
        assert np.all(np.abs(b.sample_ticks() - truth.ticks[sel]) <= 1.0)


def test_radio_bursts_buffer_and_keep_order():
    config = StationConfig(n_sensors=3, rate_hz=200, burst_probability=0.2, burst_duration_s=0.3,
                           status_interval_s=0.1, autostart=True, seed=12)
    station = BaseStation(config)
    frames = _run(station, 10.0, step_s=0.05)
    statuses = [f.message for f in frames if isinstance(f.message, Status)]
    assert max(s.buffered_samples for s in statuses) >= 3 * 200 * 0.2
    assert all(s.flags & StationFlags.STREAMING for s in statuses)
    for sid in range(3):
        counters = [f.message.first_sample_counter for f in frames
                    if isinstance(f.message, SampleBatch) and f.message.sensor_id == sid]
        assert counters == sorted(counters) and np.all(np.diff(counters) == 5)
    sent = station.truth.frames()
    for sid in range(3):
        arrivals = sent.t_sent_s[[b.frame for b in station.truth.batches if b.sensor_id == sid and b.frame >= 0]]
        gaps = np.diff(arrivals)
        assert gaps.max() > 0.25 and np.sum(gaps < 1e-9) > 20       # an outage, then its queue in one burst


def test_unplug_loses_in_flight_data_and_replug_reboots():
    config = StationConfig(n_sensors=2, autostart=True, latency_s=0.05, tick_offset=123_456_789, seed=8)
    link = EmulatorLink(BaseStation(config))
    decoder = StreamDecoder()
    frames = []
    for _ in range(20):
        link.advance(0.1)
        frames += decoder.feed(link.take())
    link.advance(0.03)
    link.unplug()                          # 30 ms of output taken by nobody + 50 ms radio latency in flight
    link.advance(1.0)
    assert link.take() == b""
    link.replug()
    link.advance(0.5)
    after = decoder.feed(link.take())
    station = link.station
    truth = station.truth.samples()
    lost = truth.fate == Fate.LOST_UNPLUGGED
    assert lost.sum() >= 2 * 100 * 0.05
    assert np.all(truth.t_true_s[lost] > 1.9)
    assert_matches_ground_truth(frames, station, boot=0)
    hello = after[0].message
    assert isinstance(hello, Hello) and after[0].seq == 0 and hello.boot_id != frames[0].message.boot_id
    assert decoder.stats.seq_resets == 0 and decoder.stats.seq_gaps == 0
    assert station.streaming                                   # autostart firmware streams from every boot...
    first_after = next(f.message for f in after if isinstance(f.message, SampleBatch))
    assert first_after.first_sample_counter == 0 and truth.boot.max() == 1      # ...with counters from 0
    link.write(encode(Command(1, Opcode.REQUEST_CLOCK_SYNC), 1, 0))
    link.advance(0.01)
    sync = [f.message for f in decoder.feed(link.take()) if isinstance(f.message, ClockSync)]
    assert sync == [ClockSync(500_000, 0, 1)]                   # ...and the tick register restarted at 0


def test_config_errors_name_the_problem():
    with pytest.raises(ValueError, match="rate 33 Hz not in"):
        StationConfig(rate_hz=33)
    with pytest.raises(ValueError, match="radio_loss 1.5 not a probability"):
        StationConfig(radio_loss=1.5)
    with pytest.raises(ValueError, match="motion source has 2 sensors, station needs 6"):
        BaseStation(StationConfig(), StillSource(2))


def test_still_source_orientation_reaches_the_wire():
    half = np.sqrt(0.5)
    q = np.array([[1, 0, 0, 0], [half, half, 0, 0], [0, 1, 0, 0]], float)   # identity, +90 deg about X, 180 about X
    station = BaseStation(StationConfig(n_sensors=3, range_g=2, autostart=True), StillSource(3, q))
    frames = _run(station, 0.5)
    mean = {sid: np.mean([f.message.acc_g() for f in frames
                          if isinstance(f.message, SampleBatch) and f.message.sensor_id == sid], axis=(0, 1))
            for sid in range(3)}
    np.testing.assert_allclose(mean[0], [0, 1, 0], atol=1e-4)
    np.testing.assert_allclose(mean[1], [0, 0, -1], atol=1e-4)     # world up seen from a sensor tipped about X
    np.testing.assert_allclose(mean[2], [0, -1, 0], atol=1e-4)


def test_trace_source_interpolates_and_loops():
    acc = np.zeros((4, 1, 3))
    acc[:, 0, 0] = [0.0, 1.0, 3.0, -1.0]
    src = TraceSource(acc, fps=2.0)
    got = src.acceleration_g(np.array([0.0, 0.25, 0.5, 1.25, 1.75, 2.0, 2.25]))[:, 0, 0]
    np.testing.assert_allclose(got, [0.0, 0.5, 1.0, 1.0, -0.5, 0.0, 0.5])
    with pytest.raises(ValueError, match="NaN"):
        TraceSource(np.full((3, 1, 3), np.nan), 10)


def test_trace_file_errors_name_the_file(tmp_path):
    bad = tmp_path / "bad.npy"
    np.save(bad, np.zeros((5, 2)))
    with pytest.raises(ValueError, match=r"bad\.npy: trace must be \(frames, sensors, 3\)"):
        TraceSource.from_npy(bad, 100)
    with pytest.raises(ValueError, match="missing.npy: cannot read trace"):
        TraceSource.from_npy(tmp_path / "missing.npy", 100)


def test_mocap_source_drives_the_station():
    mocap = pytest.importorskip("engine.mocap")
    clip = mocap.sample_clips()["16_01"]
    source = MocapSource.from_clip(clip)
    assert source.n_sensors == 6 and source.fps == 120.0
    station = BaseStation(StationConfig(n_sensors=6, rate_hz=200, range_g=16, autostart=True), source)
    frames = _run(station, 2.0)
    truth = station.truth.samples()
    np.testing.assert_allclose(truth.acc_true_g, source.acceleration_g(truth.t_true_s)[
        np.arange(len(truth.t_true_s)), truth.sensor_id])
    assert truth.acc_true_g.std() > 0.1                                 # real motion, not a still pose
    assert any(isinstance(f.message, SampleBatch) for f in frames)


def test_still_orientation_station_reports_its_pose_in_the_device_earth_frame():
    """A still sensor tipped +90 degrees about world X: its filter (Z up) reports that rotation turned into the
    Z-up frame, its gyro reads 0, and its gravity direction in the quaternion agrees with its accelerometer."""
    half = np.sqrt(0.5)
    q_world = np.array([[1, 0, 0, 0], [half, half, 0, 0]], float)
    station = BaseStation(StationConfig(n_sensors=2, autostart=True, orientation=True), StillSource(2, q_world))
    hello = station._hello()
    assert all(s.kind == 7 for s in hello.sensors)                      # accelerometer | orientation | angular rate
    frames = [f.message for f in _run(station, 0.5) if isinstance(f.message, SampleBatch)]
    assert frames and all(b.quat_q14 is not None and b.gyro_counts is not None for b in frames)
    for b in frames:
        q = b.quat_wxyz()
        # rotate(q, acc) points up in the device earth frame: gravity reaction = +Z there
        w, x, y, z = q.T
        up_in_sensor = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1)
        np.testing.assert_allclose(up_in_sensor, b.acc_g(), atol=2e-3)
        assert not b.gyro_rps().any()


def test_mocap_orientation_station_sends_the_error_model_readings_and_records_them():
    mocap = pytest.importorskip("engine.mocap")
    source = MocapSource.from_clip(mocap.sample_clips()["16_01"], orientation_seed=4)
    station = BaseStation(StationConfig(n_sensors=6, rate_hz=100, autostart=True, orientation=True), source)
    batches = [f.message for f in _run(station, 2.0) if isinstance(f.message, SampleBatch)]
    truth = station.truth.samples()
    rows = np.arange(len(truth.t_true_s))
    np.testing.assert_allclose(truth.quat_true_wxyz, source.orientation_wxyz(truth.t_true_s)[rows, truth.sensor_id])
    np.testing.assert_allclose(truth.gyro_true_rps, source.angular_rate_rps(truth.t_true_s)[rows, truth.sensor_id])
    assert np.abs(truth.gyro_true_rps).max() > 1.0                     # a moving body
    sent = {(b.sensor_id, b.first_sample_counter + i): (b.quat_wxyz()[i], b.gyro_rps()[i])
            for b in batches for i in range(b.n_samples)}
    for k in range(0, len(rows), 97):
        q, g = sent[(int(truth.sensor_id[k]), int(truth.counter[k]))]
        true_q = truth.quat_true_wxyz[k]
        assert abs(abs(float(q @ true_q)) - 1.0) < 1e-7                  # Q2.14: within 0.01 degrees
        np.testing.assert_allclose(g, truth.gyro_true_rps[k], atol=station.gyro_scale_rps_per_lsb)
    with pytest.raises(ValueError, match="gives no orientation"):
        BaseStation(StationConfig(orientation=True), TraceSource(np.zeros((3, 6, 3)), 10))
