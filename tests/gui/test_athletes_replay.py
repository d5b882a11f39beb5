"""Accuracy per athlete equals the single-athlete figures (issue 20), as a known answer: two different short held-out
takes worn by two athletes (a two-`[[athletes]]` court map, the hello the gateway builds from it), their streams
interleaved and routed by the console's per-athlete path; each athlete's poses must equal, bit for bit, the poses of
its take run alone (same path, one athlete) and offline (`synthesize_streams`): the engines share no state. The
athletes' poses must differ from each other (each engine got its own sensors and camera track, not the other's)."""
from __future__ import annotations

import numpy as np
import pytest

from engine.evaluation.takes import chain_clips
from engine.mocap import load_clip, sample_clips
from engine.stream.databases import engine_spec
from engine.stream.session import synthesize_streams
from gateway.athletes import AthleteConfig, AthleteMap, SensorRef, athletes_info
from gui.athletes_replay import athlete_stations, in_stream_order, simulate_athlete, synthesize_athletes
from gui.engine_link import synthesis_setup, worn_sensors

HELD = {"alice": ["16_05", "16_21"], "bob": ["16_11", "16_45"]}


def joints(poses) -> np.ndarray:
    return np.stack([p.joint_positions_m for p in poses])


@pytest.fixture(scope="module")
def two_athletes():
    spec, _ = engine_spec("motion-graph", n_worn=6, exclude=HELD["alice"] + HELD["bob"])
    n = len(spec.sensor_names)
    hello = athletes_info(AthleteMap([AthleteConfig("alice", "near", tuple(SensorRef.parse(f"sn0xC0DE0001:{k}")
                                                                                for k in range(n))),
                                      AthleteConfig("bob", "far", tuple(SensorRef.parse(f"st2:{k}")
                                                                        for k in range(n)))]))
    stations = [{"station": "st7", "station_serial": 0xC0DE0001, "sensors": [{"sensor": k} for k in range(n)]},
                {"station": "st2", "sensors": [{"sensor": k} for k in range(n)]}]
    routing = athlete_stations(hello, stations)
    clips = sample_clips()
    names = list(clips)
    motions = [load_clip(clips[c]) for c in names]
    setups, sims = {}, {}
    for seed, (name, station) in enumerate(routing.items()):
        setups[name] = synthesis_setup(spec, worn_sensors(list(spec.sensor_names), station)[0], lag_s=0.3)
        take = chain_clips(motions, [names.index(c) for c in HELD[name]], names, max_clip_s=1.5)
        sims[name] = simulate_athlete(name, station, take, spec.sensor_names, 50.0 + 0.23 * seed, seed)
    together = synthesize_athletes(setups, in_stream_order(*(s.messages for s in sims.values())))
    return spec, routing, setups, sims, together


def test_hello_routes_each_athlete_to_its_own_station(two_athletes):
    _, routing, setups, _, _ = two_athletes
    assert routing == {"alice": "st7", "bob": "st2"}  # alice by her station's HELLO serial, bob by station id
    assert {st for st, _ in setups["alice"].sensors} == {"st7"}


def test_each_athletes_poses_equal_its_take_run_alone_bit_for_bit(two_athletes):
    spec, _, setups, sims, together = two_athletes
    for name, setup in setups.items():
        alone = synthesize_athletes({name: setup}, sims[name].messages)[name]
        offline = synthesize_streams(lambda: spec.live(setup.lag_s), sims[name].streams, setup.sensors,
                                     spec.rate_hz)[0]
        # a ~3 s take at 30 Hz: every frame decided (the last ones at the flush) but the first (its window starts
        # before the first sample) and the last (no camera fix after it)
        assert len(together[name]) == len(alone) == len(offline) >= int(sims[name].take.duration_s * 30) - 2
        assert [p.frame for p in together[name]] == [p.frame for p in alone]
        np.testing.assert_array_equal(joints(together[name]), joints(alone))
        np.testing.assert_array_equal(joints(together[name]), joints(offline))


def test_athletes_do_not_take_each_others_inputs(two_athletes):
    _, _, _, sims, together = two_athletes
    n = min(len(together["alice"]), len(together["bob"]))
    gap_m = np.linalg.norm(joints(together["alice"])[:n] - joints(together["bob"])[:n], axis=2).mean()
    assert gap_m > 0.05  # different takes, different camera tracks: different skeletons
    # each athlete's root follows its own camera track (its take's truth ground position), not the other's
    for name, sim in sims.items():
        root = joints(together[name])[:, 0, [0, 2]]
        times = np.array([p.t_s for p in together[name]]) - sim.offset_s
        truth = np.stack([np.interp(times, np.arange(sim.take.n_frames) / sim.take.fps, sim.take.ground_m[:, k])
                          for k in (0, 1)], axis=1)
        assert np.sqrt(np.mean(np.sum((root - truth) ** 2, axis=1))) < 0.15
