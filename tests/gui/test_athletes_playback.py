"""Playback of a two-athlete take (issue 20): a take recorded by the gateway's recorder with samples tagged alice
(st1) and bob (st2) and one camera track each; `courtside console --playback TAKE --save-poses` (the play button
pressed) synthesises every athlete the recording names, each from its own station and camera track: each saved
file's poses equal the offline synthesis of its athlete's own streams, bit for bit, for every frame the console
decided."""
from __future__ import annotations

import json

import numpy as np

from engine.evaluation.takes import chain_clips
from engine.mocap import load_clip, sample_clips
from engine.stream.databases import engine_spec
from engine.stream.session import synthesize_streams
from gateway.recorder import Recorder
from gui.athletes_replay import simulate_athlete
from gui.cli import console_main
from gui.main_window import ConsoleWindow
from gui.playback import Playback
from PySide6 import QtCore

SENSORS = ("left_forearm", "right_forearm", "left_shin", "right_shin", "lower_back", "chest")


def record_two_athletes(tmp_path):
    """The take file, and each athlete's simulated streams (alice walks 16_05, bob runs 16_45 after 16_11)."""
    clips = sample_clips()
    names = list(clips)
    motions = [load_clip(clips[c]) for c in names]
    sims = {name: simulate_athlete(name, station, chain_clips(motions, [names.index(c) for c in held], names,
                                                              max_clip_s=1.5), SENSORS, 20.0 + 0.3 * seed, seed)
            for seed, (name, station, held) in enumerate([("alice", "st1", ["16_05", "16_21"]),
                                                         ("bob", "st2", ["16_11", "16_45"])])}
    recorder = Recorder(tmp_path / "takes")
    recorder.start("rally")
    for sim in sims.values():
        for msg in sim.messages:
            if msg.kind == "samples":
                recorder.put_samples(msg["station"], msg["sensor"], msg.arrays, header={"athlete": msg["athlete"]})
            else:
                recorder.put("camera", msg.header)
    return recorder.stop()["files"][0], sims


def test_playback_synthesises_every_athlete_the_take_names(qapp, tmp_path):
    take, sims = record_two_athletes(tmp_path)
    assert Playback(take).athlete_stations() == {"alice": "st1", "bob": "st2"}
    out = tmp_path / "poses.npz"

    def press_play() -> None:  # the operator's play button, once the console's window is up
        for window in qapp.topLevelWidgets():
            if isinstance(window, ConsoleWindow):
                window.playbar.play_button.setChecked(True)

    QtCore.QTimer.singleShot(500, press_play)
    assert console_main(["--playback", take, "--duration", "6", "--save-poses", str(out)]) == 0
    spec, _ = engine_spec(None, n_worn=6)
    for path, name in ((out, "alice"), (tmp_path / "poses.bob.npz", "bob")):
        data = np.load(path)
        meta = json.loads(str(data["meta_json"]))
        assert meta["athlete"] == name
        assert {s["stream"].split("/")[0] for s in meta["sensors"]} == {sims[name].station}
        assert meta["frames_with_camera"] > 0.9 * meta["frames_in"]  # its own track, every frame
        sim = sims[name]
        offline = synthesize_streams(lambda: spec.live(0.5), sim.streams, [(sim.station, k) for k in range(6)],
                                     spec.rate_hz)[0]
        live = data["joint_positions_m"]
        # the console stops before the engine's last lag is decided; every frame it decided is offline's
        assert 0.7 * len(offline) <= len(live) <= len(offline)
        np.testing.assert_array_equal(live, np.stack([p.joint_positions_m for p in offline[:len(live)]]))
