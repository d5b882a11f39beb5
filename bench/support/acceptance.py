"""Acceptance: 4 emulated stations x 6 sensors x 100 Hz over real ptys, with radio loss, wire corruption and
unplug/replugs, plus the synthetic court camera, running faster than real time.

Scored against the emulator's ground truth: the recording holds exactly the samples the stations delivered, every
sample's gateway time is within 1 ms (p99) of the truth after the 30 s warm-up (counted from each boot: a replug
is a reboot), and every replugged station streams again within 2 s. The take ends by pulling every cable, so both
the mid-run unplugs and the final ones check that the emulator's "delivered" is exactly what reached the gateway:
nothing may be missing or extra. Camera observations are recorded and streamed alongside, stamped on the same
gateway clock (inside the take's span).

`run_acceptance(span_s, speed, n_unplugs)` is the whole run; it returns an `AcceptanceRun` whose `failures()`
lists every criterion missed and whose `summary()` prints the figures. The suite
(tests/gateway/test_acceptance_emulated.py) runs 60 s emulated at 2x and
3 min emulated at 2x with 3 unplugs; the 10-minute case of the issue runs from the bench
(`bench/bench_gateway.py --acceptance-minutes 10`, see docs/gateway.md "Acceptance").

Why 2x and not faster: everything shares one process, whose CPU need grows with the speed (3x took 1.25 of the
2-core CI box's cores and missed the 1 ms clock limit at load 2.6), and a host stall covers `speed` times more of
the clock's device-time window. The 1 ms limit is not relaxed for a busy machine; instead every run measures how
late the host delivered the fastest clock beacons (`AcceptanceRun.host_starved`), so a clock failure on a starved
host says so, and a pass on one warns."""
from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from firmware_protocol.emulator import Fate
from gateway.camera.service import CameraService
from gateway.client import GatewayClient
from gateway.daemon import Gateway
from firmware_protocol.emulator.stations import demo_config, start_emulated_station
from gateway.recorder import load_take, realign_take

WARMUP_S = 30.0
UNPLUG_FOR_S = 0.5
RECONNECT_LIMIT_S = 2.0
CLOCK_P99_LIMIT_S = 1e-3
N_STATIONS = 4
# Host starvation (see `AcceptanceRun.host_starved`): the fastest clock beacon of each station in each host second
# is the best evidence the lower-envelope clock had; when in the median second even that one reached the gateway
# this late, the evidence sits half the error budget above the truth and the clock figures describe the machine.
FLOOR_CELL_S = 1.0
STARVED_FLOOR_S = 0.5e-3


def _emulated_now(em) -> float:
    return (time.monotonic() - em.wall0_s) * em.speed


def _sleep_until(em, t_emulated_s: float) -> None:
    while (remaining := (t_emulated_s - _emulated_now(em)) / em.speed) > 0:
        time.sleep(min(remaining, 0.2))


def unplug_schedule(span_s: float, n_unplugs: int, first_s: float = 12.0) -> list[tuple[int, float]]:
    """(station index, emulated time) of each mid-run unplug: the first at ``first_s``, then evenly spaced over
    the rest of the span; stations take turns (st1, st2, st3, st4, st1, ...)."""
    step = (span_s - first_s) / max(n_unplugs, 1)
    return [(k % N_STATIONS, first_s + k * step) for k in range(n_unplugs)]


def _key(boot, sensor, counter) -> np.ndarray:
    """(boot/epoch, sensor, counter) packed into one int64 for set operations."""
    return (np.asarray(boot, np.int64) << 40) | (np.asarray(sensor, np.int64) << 32) | np.asarray(counter, np.int64)


@dataclass
class AcceptanceRun:
    span_s: float
    speed: float
    unplugs: list[tuple[int, float]]
    wall_s: float = 0.0
    cpu_s: float = 0.0
    load_at_start: float = 0.0
    other_cpu_s: float = 0.0  # CPU time other processes used on this machine during the run (/proc/stat)
    beacon_floor_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # per station-second, see FLOOR_CELL_S
    delivered: dict[str, int] = field(default_factory=dict)  # emulator ground truth, per station
    recorded: dict[str, int] = field(default_factory=dict)
    missing: dict[str, int] = field(default_factory=dict)
    extra: dict[str, int] = field(default_factory=dict)
    duplicated: dict[str, int] = field(default_factory=dict)
    radio_dropped: dict[str, int] = field(default_factory=dict)
    lost_unplugged: dict[str, int] = field(default_factory=dict)
    wire_errors: dict[str, int] = field(default_factory=dict)  # crc + framing errors seen by the gateway
    reconnect_s: list[float] = field(default_factory=list)
    online_err_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # after warm-up
    offline_err_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # every sample
    samples_written: int = 0
    displayed: int = 0
    camera_recorded: int = 0
    camera_tracked: int = 0  # recorded observations with a position
    camera_outside_span: int = 0
    camera_streamed: int = 0
    camera_thumbnails: int = 0
    problem: str | None = None
    notes: list[str] = field(default_factory=list)

    def failures(self) -> list[str]:
        out = list(self.notes)
        if self.problem is not None:
            out.append(f"recording problem: {self.problem}")
        for name in self.delivered:
            if self.missing[name] or self.extra[name] or self.duplicated[name]:
                out.append(f"{name}: recorded {self.recorded[name]} vs delivered {self.delivered[name]}: missing "
                           f"{self.missing[name]}, extra {self.extra[name]}, duplicated {self.duplicated[name]}")
            if not self.radio_dropped[name]:
                out.append(f"{name}: no radio loss injected")
            if not self.lost_unplugged[name]:
                out.append(f"{name}: no cable pulled mid-stream")
        if self.delivered and not self.wire_errors.get("st1"):
            out.append("st1: no wire corruption seen by the gateway")
        if len(self.reconnect_s) != len(self.unplugs):
            out.append(f"{len(self.reconnect_s)} reconnects for {len(self.unplugs)} unplugs")
        if self.reconnect_s and max(self.reconnect_s) >= RECONNECT_LIMIT_S:
            out.append(f"reconnect {max(self.reconnect_s):.2f} s >= {RECONNECT_LIMIT_S} s")
        recorded = sum(self.recorded.values())
        if self.online_err_s.size < 0.25 * recorded:
            out.append(f"only {self.online_err_s.size} of {recorded} samples past warm-up")
        clock = []
        if self.online_err_s.size and np.percentile(self.online_err_s, 99) >= CLOCK_P99_LIMIT_S:
            clock.append(f"online p99 clock error {np.percentile(self.online_err_s, 99) * 1e3:.3f} ms")
        if self.offline_err_s.size and np.percentile(self.offline_err_s, 99) >= CLOCK_P99_LIMIT_S:
            clock.append(f"offline p99 clock error {np.percentile(self.offline_err_s, 99) * 1e3:.3f} ms")
        if clock and self.host_starved:
            clock.append(f"HOST STARVED ({self.host_report()}): the clock figures measure this machine, not the "
                         "estimator; rerun on a machine with a core to spare")
        out += clock
        # the display path ran alongside (it may drop for a slow client; recording never does)
        if self.displayed <= 0.5 * self.samples_written:
            out.append(f"client displayed {self.displayed} of {self.samples_written} samples")
        if self.camera_tracked == 0 or self.camera_outside_span:
            out.append(f"camera: {self.camera_tracked} tracked observations recorded, "
                       f"{self.camera_outside_span} stamped outside the take")
        if self.camera_streamed == 0 or self.camera_thumbnails == 0:
            out.append(f"camera: {self.camera_streamed} observations, {self.camera_thumbnails} thumbnails streamed")
        return out

    @property
    def host_starved(self) -> bool:
        """True when the host delivered the clock evidence too late to judge the clock against its 1 ms limit:
        in the median station-second even the fastest beacon (emulator -> pty -> gateway stamp) was
        `STARVED_FLOOR_S` late. Measured from the recording and the emulator's truth, independent of the estimator.
        Why it exists: on a CPU-starved machine the lowest-latency packets are late as well, so the lower envelope
        rises and online/offline clock errors grow although the estimator is right; the test still fails then,
        but says so instead of blaming the estimator (and warns when it passed anyway)."""
        return bool(self.beacon_floor_s.size and np.median(self.beacon_floor_s) >= STARVED_FLOOR_S)

    def host_report(self) -> str:
        floor = self.beacon_floor_s * 1e3
        if not floor.size:
            return "no clock beacons recorded"
        return (f"fastest beacon per station-second p50 {np.median(floor):.2f} / p90 {np.percentile(floor, 90):.2f} "
                f"ms late; other processes used {self.other_cpu_s / max(self.wall_s, 1e-9):.2f} of "
                f"{os.cpu_count()} cores, this one {self.cpu_s / max(self.wall_s, 1e-9):.2f}")

    def summary(self) -> str:
        def ms(a: np.ndarray) -> str:
            if not a.size:
                return "n/a"
            return (f"p50 {np.percentile(a, 50) * 1e3:.3f} / p99 {np.percentile(a, 99) * 1e3:.3f} / "
                    f"max {a.max() * 1e3:.3f} ms over {a.size} samples")
        lines = [f"{self.span_s:.0f} s emulated at {self.speed:g}x, {len(self.unplugs)} mid-run unplugs "
                 f"({', '.join(f'st{i + 1}@{t:.0f}s' for i, t in self.unplugs)}): wall {self.wall_s:.1f} s, "
                 f"process CPU {self.cpu_s:.1f} s, load {self.load_at_start:.1f} at start"]
        for name in self.delivered:
            lines.append(f"  {name}: delivered {self.delivered[name]}, recorded {self.recorded[name]} (missing "
                         f"{self.missing[name]}, extra {self.extra[name]}, dup {self.duplicated[name]}); radio-dropped "
                         f"{self.radio_dropped[name]}, lost at unplug {self.lost_unplugged[name]}, wire errors "
                         f"{self.wire_errors[name]}")
        lines.append(f"  host: {self.host_report()}{' (STARVED)' if self.host_starved else ''}")
        lines.append(f"  clock online after warm-up: {ms(self.online_err_s)}")
        lines.append(f"  clock offline re-fit, every sample: {ms(self.offline_err_s)}")
        lines.append(f"  reconnect after replug: {', '.join(f'{r:.2f}' for r in self.reconnect_s) or 'n/a'} s")
        lines.append(f"  display: {self.displayed} of {self.samples_written} samples; camera: {self.camera_recorded} "
                     f"recorded ({self.camera_tracked} tracked, {self.camera_outside_span} outside the take), "
                     f"{self.camera_streamed} streamed, {self.camera_thumbnails} thumbnails")
        failures = self.failures()
        lines.append("  PASS" if not failures else "  FAIL: " + "; ".join(failures))
        return "\n".join(lines)


def _cpu_s() -> float:
    t = os.times()
    return t.user + t.system


def _machine_busy_s() -> float:
    """CPU time all processes on this machine have used since boot (/proc/stat; 0 where there is none)."""
    try:
        with open("/proc/stat") as f:
            ticks = [int(v) for v in f.readline().split()[1:8]]  # user nice system idle iowait irq softirq
    except OSError:
        return 0.0
    return (sum(ticks) - ticks[3] - ticks[4]) / os.sysconf("SC_CLK_TCK")


def beacon_latency_s(em, points: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(host arrival s, delivery latency s) of every recorded clock beacon of emulated station ``em``: the
    gateway's arrival stamp minus the host time the station sent it (the emulator's truth, matched by boot and raw
    ticks). Beacons have no radio leg, so this is the host's own share: emulator thread -> pty -> gateway stamp."""
    beacons = em.station.truth.beacons()
    truth_keys = _key(beacons.boot, 0, beacons.ticks)
    order = np.argsort(truth_keys, kind="stable")
    got = _key(points["epoch"], 0, points["raw_ticks"])
    pos = np.minimum(np.searchsorted(truth_keys[order], got), max(order.size - 1, 0))
    known = truth_keys[order][pos] == got if order.size else np.zeros(got.size, bool)
    arrival = np.asarray(points["arrival_s"], np.float64)[known]
    return arrival, arrival - em.true_to_host(beacons.t_true_s[order[pos[known]]])


def cell_minima(t_s: np.ndarray, values: np.ndarray, cell_s: float) -> np.ndarray:
    """The smallest of ``values`` in each ``cell_s`` long cell of ``t_s`` that holds any."""
    cells, inverse = np.unique(np.floor(t_s / cell_s).astype(np.int64), return_inverse=True)
    out = np.full(cells.size, np.inf)
    np.minimum.at(out, inverse, values)
    return out


def run_acceptance(tmp_path: Path, span_s: float = 60.0, speed: float = 2.0, n_unplugs: int = 1,
                   seed: int = 42, camera: bool = True) -> AcceptanceRun:
    """One acceptance run; never asserts (see `AcceptanceRun.failures`)."""
    tmp_path = Path(tmp_path)
    run = AcceptanceRun(span_s, speed, unplug_schedule(span_s, n_unplugs), load_at_start=os.getloadavg()[0])
    wall0, cpu0, busy0 = time.monotonic(), _cpu_s(), _machine_busy_s()
    rng = np.random.default_rng(seed)
    stations = [start_emulated_station(demo_config(i, rng, radio_loss=0.01, byte_corruption=2e-5,
                                                   burst_probability=0.01),
                                       path=tmp_path / f"station{i + 1}", speed=speed) for i in range(N_STATIONS)]
    # the camera runs in real time (wall clock) whatever the stations' speed: its frames are stamped on the
    # gateway's monotonic clock, which is what the check below verifies
    cam = CameraService.synthetic(span_s / speed + 30.0, seed=seed, thumbnail_every=10) if camera else None
    gw = Gateway([s.path for s in stations], listen=("127.0.0.1", 0), record_dir=tmp_path / "rec", camera=cam,
                 status_interval_s=0.5, reconnect_interval_s=0.05)
    lock = threading.Lock()
    streamed = {"samples": 0, "camera": 0, "jpeg": 0}

    def on_samples(m) -> None:
        with lock:
            streamed["samples"] += len(m["counter"])

    def on_camera(m) -> None:
        with lock:
            streamed["camera"] += 1
            streamed["jpeg"] += "jpeg" in m.arrays

    ref = stations[0]
    try:
        take_start = time.monotonic()
        gw.handle_request("start_recording", {"take": "acceptance"})  # before any station connects
        gw.start()
        client = GatewayClient(*gw.address).connect()
        client.add_listener("samples", on_samples)
        client.add_listener("camera", on_camera)

        for index, t_unplug in run.unplugs:
            # by source path: the reader is named st<id> only once the station's first frame has arrived
            em, reader = stations[index], gw.reader(str(stations[index].path))
            _sleep_until(ref, t_unplug)
            epoch_before = reader.unwrapper.epoch if reader is not None and reader.unwrapper else -1
            em.unplug()
            _sleep_until(ref, t_unplug + UNPLUG_FOR_S)
            received_before = reader.sensors[0].received
            em.replug()
            replugged_at = time.monotonic()
            while (reader.unwrapper.epoch <= epoch_before or reader.sensors[0].received <= received_before
                   or reader.link_state != "streaming"):
                if time.monotonic() - replugged_at > 2 * RECONNECT_LIMIT_S:
                    run.notes.append(f"st{index + 1}: no data within {2 * RECONNECT_LIMIT_S} s of the replug at "
                                     f"{t_unplug:.0f} s")
                    break
                time.sleep(0.01)
            else:
                run.reconnect_s.append(time.monotonic() - replugged_at)

        _sleep_until(ref, span_s)
        # end of take: pull every cable mid-stream, then wait until the gateway has processed what it read
        for s in stations:
            s.unplug()
        quiet_since, last_count = time.monotonic(), gw.samples_in
        while time.monotonic() - quiet_since < 0.5:
            time.sleep(0.05)
            if gw.samples_in != last_count:
                quiet_since, last_count = time.monotonic(), gw.samples_in
        status = gw.status()
        final = gw.handle_request("stop_recording", {})
        take_end = time.monotonic()
        client.close()
    finally:
        gw.stop()
        for s in stations:
            s.stop()
    run.wall_s, run.cpu_s = time.monotonic() - wall0, _cpu_s() - cpu0
    run.other_cpu_s = max(_machine_busy_s() - busy0 - run.cpu_s, 0.0)
    run.samples_written, run.displayed = final["samples_written"], streamed["samples"]
    run.camera_streamed, run.camera_thumbnails = streamed["camera"], streamed["jpeg"]

    take = load_take(final["files"][0])
    run.problem = take.problem
    cameras = [m.header for m in take.others if m.kind == "camera"]
    run.camera_recorded = len(cameras)
    run.camera_tracked = sum("position_m" in h for h in cameras)
    run.camera_outside_span = sum(not (take_start <= h["t_host_s"] <= take_end) for h in cameras)

    realigned = realign_take(take)
    online, offline, floors = [], [], []
    for index, em in enumerate(stations):
        name = f"st{index + 1}"
        if name in take.clock_points:
            arrival, latency = beacon_latency_s(em, take.clock_points[name])
            floors.append(cell_minima(arrival - wall0, latency, FLOOR_CELL_S))
        truth = em.station.truth.samples()
        truth_keys = _key(truth.boot, truth.sensor_id, truth.counter)
        order = np.argsort(truth_keys, kind="stable")
        sorted_keys = truth_keys[order]
        assert np.all(np.diff(sorted_keys) > 0), "emulator ground truth keys are not unique"
        delivered = truth.fate == Fate.DELIVERED
        boot_start = {int(b): float(truth.t_true_s[truth.boot == b].min()) for b in np.unique(truth.boot)}
        keys, t_host, t_off = [], [], []
        for (station, sensor), cols in take.samples.items():
            if station != name:
                continue
            # clock epoch == boot index: one epoch per reboot, none spurious
            keys.append(_key(cols["epoch"], sensor, cols["counter"]))
            t_host.append(np.asarray(cols["t_host_s"], np.float64))
            t_off.append(np.asarray(realigned[(station, sensor)], np.float64))
        keys = np.concatenate(keys) if keys else np.zeros(0, np.int64)
        t_host = np.concatenate(t_host) if t_host else np.zeros(0)
        t_off = np.concatenate(t_off) if t_off else np.zeros(0)
        want = truth_keys[delivered]
        run.delivered[name], run.recorded[name] = int(want.size), int(keys.size)
        run.duplicated[name] = int(keys.size - np.unique(keys).size)
        run.missing[name] = int(np.setdiff1d(want, keys).size)
        run.extra[name] = int(np.setdiff1d(keys, want).size)
        run.radio_dropped[name] = int((truth.fate == Fate.RADIO_DROPPED).sum())
        run.lost_unplugged[name] = int((truth.fate == Fate.LOST_UNPLUGGED).sum())
        st = next(s for s in status["stations"] if s["station"] == name)
        run.wire_errors[name] = int(st["crc_errors"] + st["framing_errors"])
        # score every recorded sample that the ground truth knows (extras are reported above)
        pos = np.minimum(np.searchsorted(sorted_keys, keys), sorted_keys.size - 1)
        known = sorted_keys[pos] == keys
        rows = order[pos[known]]
        t_true_host = em.true_to_host(truth.t_true_s[rows])
        boots = truth.boot[rows]
        age = truth.t_true_s[rows] - np.array([boot_start[int(b)] for b in np.unique(boots)])[
            np.searchsorted(np.unique(boots), boots)]
        err = t_host[known] - t_true_host
        online.append(np.abs(err[age > WARMUP_S]))
        offline.append(np.abs(t_off[known] - t_true_host))
    run.online_err_s, run.offline_err_s = np.concatenate(online), np.concatenate(offline)
    run.beacon_floor_s = np.concatenate(floors) if floors else np.zeros(0)
    return run
