"""One calibration wizard per athlete behind the gateway's single calibration hook (issue 20).

Why a router and not one wizard over every sensor: each athlete calibrates on their own (stands in the N-pose,
walks) while the other keeps playing, so each needs their own wizard state, segment table and saved record. The
gateway tags each sample block with its athlete and calls :meth:`on_athlete_samples`; actions carry an
``athlete`` argument (default: the first athlete, so a single-athlete console needs no change).

State: the first athlete's snapshot at the top level (what a single-athlete console reads) plus ``"athlete"``
(its name) and ``"athletes"`` ``{name: snapshot}`` for every athlete. ``save`` records carry the athlete as
their subject unless the client names one, and the result says whose record it is.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from gateway.calibration.service import CalibrationService
from gateway.server import RequestError


class AthleteCalibrations:
    """The gateway's calibration hook over ``{athlete name: CalibrationService}`` (insertion order kept)."""

    def __init__(self, services: dict[str, CalibrationService]) -> None:
        if not services:
            raise ValueError("at least one athlete's calibration service")
        self.services = dict(services)
        self.default = next(iter(self.services))

    def on_athlete_samples(self, athlete: str | None, station: str, sensor: int, t_host_s: np.ndarray,
                           acc_g: np.ndarray, quat_wxyz: np.ndarray | None = None) -> None:
        """Samples of one block, to the wizard of the athlete wearing the sensor (others' wizards never see them)."""
        service = self.services.get(athlete) if athlete is not None else None
        if service is not None:
            service.on_samples(station, sensor, t_host_s, acc_g, quat_wxyz)

    def state(self) -> dict[str, Any]:
        states = {name: service.state() for name, service in self.services.items()}
        return {**states[self.default], "athlete": self.default, "athletes": states}

    def handle(self, action: str, args: dict[str, Any]) -> Any:
        """``args["athlete"]`` picks the wizard (default: the first athlete); the rest goes to that wizard.
        ``state`` without an athlete is the whole state (every athlete's snapshot)."""
        if action == "state" and "athlete" not in args:
            return self.state()
        args = dict(args)
        name = str(args.pop("athlete", self.default))
        service = self.services.get(name)
        if service is None:
            raise RequestError(f"calibration: no athlete {name!r}; athletes: {', '.join(self.services)}")
        if action == "save":
            args.setdefault("subject", name)
        result = service.handle(action, args)
        return {**result, "athlete": name} if isinstance(result, dict) else result
