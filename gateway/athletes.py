"""Athletes on one court: who wears which sensors, on which half the camera first finds them (issue 20).

A court config without ``[[athletes]]`` has one athlete, ``"player"``, wearing every sensor (no config change for
the single-athlete court). With ``[[athletes]]`` each entry names its sensors as ``"st<station id>:<index>"``
(the station's id from its frames) or ``"sn<station serial>:<index>"`` (the serial from its HELLO, decimal or
0x-hex: survives re-flashing a station id), one placement site per sensor, and its side ``near``/``far``.

Why the map is resolved per (station, sensor) and cached: the gateway tags every sample block with its athlete
on the reader thread, so the lookup must be a dict hit; a station's serial arrives with its HELLO, possibly after
its first samples, so until it is known a serial-addressed sensor is untagged (and the lookup is retried).
"""
from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

#: The single athlete's name when the config has no ``[[athletes]]`` (CONTRACTS "Two athletes").
DEFAULT_ATHLETE = "player"
_SENSOR = re.compile(r"(st|sn)(0x[0-9a-fA-F]+|\d+):(\d{1,3})")


@dataclass(frozen=True)
class SensorRef:
    """One worn sensor: ``key`` is ``"st"`` (station id) or ``"sn"`` (station serial), ``station`` that number."""

    key: str
    station: int
    index: int

    @classmethod
    def parse(cls, text: str) -> "SensorRef":
        """``"st1:0"`` / ``"sn0xC0DE0001:2"``; ValueError says what is expected."""
        match = _SENSOR.fullmatch(text.strip()) if isinstance(text, str) else None
        if match is None:
            raise ValueError(f"sensor {text!r}: expected \"st<station id>:<sensor index>\" (e.g. \"st1:0\") or "
                             "\"sn<station serial>:<sensor index>\" (e.g. \"sn0xC0DE0001:0\")")
        return cls(match[1], int(match[2], 0), int(match[3]))

    def __str__(self) -> str:
        return f"{self.key}{self.station}:{self.index}"


@dataclass(frozen=True)
class AthleteConfig:
    """One ``[[athletes]]`` entry. ``sensors=()`` means every sensor (only for the single default athlete);
    ``placements`` are the sensor sites in the order of ``sensors`` (the calibration wizard's segment table);
    ``clips`` are what its emulated stations replay (``courtside demo`` / ``stations.emulate``)."""

    name: str = DEFAULT_ATHLETE
    side: str | None = None
    sensors: tuple[SensorRef, ...] = ()
    placements: tuple[str, ...] = ()
    clips: tuple[str, ...] = ()


class AthleteMap:
    """(station name, station serial, sensor index) -> athlete name, for tagging samples."""

    def __init__(self, athletes: Sequence[AthleteConfig]) -> None:
        self.athletes = tuple(athletes)
        self.names = [a.name for a in self.athletes]
        self._by_ref = {(ref.key, ref.station, ref.index): a.name for a in self.athletes for ref in a.sensors}
        self._catch_all = next((a.name for a in self.athletes if not a.sensors), None)
        self._cache: dict[tuple[str, int], str | None] = {}

    def athlete_of(self, station: str, sensor: int, serial: int | None = None) -> str | None:
        """Who wears sensor ``sensor`` of station ``station`` (reader name ``"st<id>"``); None = nobody."""
        key = (station, int(sensor))
        if key in self._cache:
            return self._cache[key]
        name = None
        if station.startswith("st") and station[2:].isdigit():
            name = self._by_ref.get(("st", int(station[2:]), int(sensor)))
        if name is None and serial is not None:
            name = self._by_ref.get(("sn", int(serial), int(sensor)))
        if name is None:
            name = self._catch_all
        if name is not None or not any(ref[0] == "sn" for ref in self._by_ref) or serial is not None:
            self._cache[key] = name  # final unless a serial-addressed sensor may still match once HELLO arrives
        return name


def athletes_info(athletes: AthleteMap) -> list[dict]:
    """Who wears what, as the gateway's hello lists it (consoles set up one synthesis per athlete from it): name,
    side, sensors (``"st1:0"`` / ``"sn<serial>:0"``; [] = every sensor), placements."""
    return [{"name": a.name, "side": a.side, "sensors": [str(r) for r in a.sensors],
             "placements": list(a.placements)} for a in athletes.athletes]
