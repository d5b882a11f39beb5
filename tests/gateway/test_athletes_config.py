"""``[[athletes]]`` in the court config (issue 20): read, refused with file/line/key, the single-athlete default,
and the sample -> athlete map the gateway tags samples with."""
from __future__ import annotations

import pytest

from engine.errors import MalformedFileError
from gateway.athletes import AthleteConfig, AthleteMap, SensorRef
from gateway.court_config import CourtConfig, load_court_config
from tests.gateway.test_court_config import test_refusals_name_the_file_line_and_key as refused_naming_file_line_and_key
from tests.gateway.test_court_config import write

TWO = """\
[camera]
player_side = "near"

[calibration]
placements = ["chest"]

[[athletes]]
name = "alice"
side = "near"
sensors = ["st1:0", "st1:1"]
placements = ["left_forearm", "right_forearm"]
clips = ["16_05", "moves/a.bvh"]

[[athletes]]
name = "bob"
side = "far"
sensors = ["sn0xC0DE0002:0", "st2:1"]
"""


def test_two_athletes_are_read(tmp_path):
    config = load_court_config(write(tmp_path, TWO))
    alice, bob = config.athletes
    assert (alice.name, alice.side, bob.name, bob.side) == ("alice", "near", "bob", "far")
    assert alice.sensors == (SensorRef("st", 1, 0), SensorRef("st", 1, 1))
    assert bob.sensors == (SensorRef("sn", 0xC0DE0002, 0), SensorRef("st", 2, 1))
    assert alice.placements == ("left_forearm", "right_forearm") and bob.placements == ()
    assert alice.clips == ("16_05", str(tmp_path / "moves/a.bvh"))
    assert config.effective_athletes() == config.athletes


def test_no_athletes_means_one_player_wearing_everything(tmp_path):
    config = load_court_config(write(tmp_path, '[camera]\nplayer_side = "far"\n[calibration]\nplacements = ["chest"]\n'))
    assert config.athletes == ()
    (player,) = config.effective_athletes()
    assert player == AthleteConfig("player", "far", (), ("chest",), ())
    assert AthleteMap(config.effective_athletes()).athlete_of("st7", 3) == "player"
    assert CourtConfig().effective_athletes()[0].name == "player"


@pytest.mark.parametrize("text, line, fragment", [
    ('[[athletes]]\nname = "a"\nsensors = ["st1"]\n', 3, "athletes.sensors: athlete 1: sensor 'st1': expected"),
    ('[[athletes]]\nname = "a"\nsensors = ["st1:0", "st1:0"]\n', 3, "listed twice"),
    ('[[athletes]]\nname = "a"\nheight = 2\n', 3, "athletes.height: unknown key in athlete 1"),
    ('[[athletes]]\nname = "a/b"\n', 2, "contains a path separator"),
    ('[[athletes]]\nname = "a"\nside = "left"\n', 3, "athletes.side: athlete 1: expected one of"),
    ('[[athletes]]\nname = "a"\nplacements = ["tail"]\n', 3, "unknown sensor site(s) ['tail']"),
    ('athletes = 3\n', 1, "expected [[athletes]] tables"),
])
def test_bad_athlete_keys_name_file_line_and_key(tmp_path, text, line, fragment):
    refused_naming_file_line_and_key(tmp_path, text, line, fragment)  # the same check as every other key


@pytest.mark.parametrize("text, fragment", [
    ('[[athletes]]\nside = "near"\n', "athlete 1 has no name"),
    ('[[athletes]]\nname = "a"\n[[athletes]]\nname = "a"\n', "the name 'a' is used twice"),
    ('[[athletes]]\nname = "a"\nside = "near"\nsensors = ["st1:0"]\n'
     '[[athletes]]\nname = "b"\nside = "far"\nsensors = ["st1:0"]\n', "sensor st1:0 is worn by both 'a' and 'b'"),
    ('[[athletes]]\nname = "a"\nside = "near"\nsensors = ["st1:0"]\n'
     '[[athletes]]\nname = "b"\nside = "near"\nsensors = ["st2:0"]\n', "each athlete needs its own side"),
    ('[[athletes]]\nname = "a"\nside = "near"\nsensors = ["st1:0"]\n'
     '[[athletes]]\nname = "b"\nside = "far"\n', "'b' lists no sensors"),
    ('[[athletes]]\nname = "a"\nsensors = ["st1:0"]\nplacements = ["chest", "left_shin"]\n',
     "lists 1 sensors but 2 placements"),
])
def test_rules_across_athletes(tmp_path, text, fragment):
    with pytest.raises(MalformedFileError, match=fragment):
        load_court_config(write(tmp_path, text))


def test_athlete_map_by_station_id_and_by_serial(tmp_path):
    amap = AthleteMap(load_court_config(write(tmp_path, TWO)).athletes)
    assert amap.athlete_of("st1", 0) == "alice" and amap.athlete_of("st1", 1) == "alice"
    assert amap.athlete_of("st2", 1) == "bob"
    assert amap.athlete_of("st1", 2) is None  # worn by nobody: untagged
    assert amap.athlete_of("st5", 0) is None  # serial not known yet (no HELLO): untagged, asked again later
    assert amap.athlete_of("st5", 0, serial=0xC0DE0002) == "bob"
    assert amap.athlete_of("st6", 0, serial=0xC0DE0003) is None
