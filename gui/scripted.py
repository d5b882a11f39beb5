"""`ScriptedRun`: unattended capture from the console — what `courtside console --calibrate --record TAKE
--duration S --save-poses OUT` runs, through the same window, wizard and request paths an operator uses.

Steps, each driven by the gateway's replies and broadcast state (a QTimer on the GUI thread polls twice a
second; nothing blocks the event loop):

1. ``--calibrate``: open the calibration wizard, assign sensors from the console's sensor map, then press "next"
   whenever the gateway's wizard waits for the operator (assign, placement, tap — skipped — and review); the
   N-pose step captures by itself once the subject is still. When the wizard is done, ask the gateway to save the
   record (it lands in the gateway's records directory). Gives up after ``calibration_timeout_s``.
2. ``--record TAKE``: start the take (the window's recording request), then after ``duration_s`` stop it; the
   console closes once the gateway confirms the stop, so the take and the saved poses cover the same frames.

Any refusal (an unauthenticated or viewer client, a take that exists, a wizard that never finishes) ends the run
with `failure` set; the CLI prints it and exits 1."""
from __future__ import annotations

import logging
import time
from typing import Any

from PySide6 import QtCore

log = logging.getLogger("courtside.console")

WAITS_FOR_OPERATOR = ("assign", "placement", "tap", "review")


class ScriptedRun(QtCore.QObject):
    def __init__(self, window: Any, *, calibrate: bool, take: str | None, duration_s: float | None,
                 calibration_timeout_s: float = 90.0, poll_ms: int = 500) -> None:
        super().__init__(window)
        self.window = window
        self.take = take
        self.duration_s = duration_s
        self.calibration_timeout_s = calibration_timeout_s
        self.phase = "calibrate" if calibrate else ("record" if take else "run")
        self.failure: str | None = None
        self.calibration_saved: dict[str, Any] | None = None
        self._t_phase = self._t_start = time.monotonic()
        # a gateway that stops answering must not keep an unattended run alive for ever
        self.budget_s = calibration_timeout_s + (duration_s or 0.0) + 60.0
        self._assigned = False
        self._pending: str | None = None  # tag of the request we wait for
        self.timer = QtCore.QTimer(self)
        self.timer.setInterval(poll_ms)
        self.timer.timeout.connect(self._poll)
        window.requests.done.connect(self._reply)

    def start(self) -> None:
        self.timer.start()
        log.info("scripted run: %s", self.phase)

    # -- plumbing -------------------------------------------------------------------------------------------------
    def _enter(self, phase: str) -> None:
        log.info("scripted run: %s -> %s", self.phase, phase)
        self.phase, self._t_phase = phase, time.monotonic()

    def _fail(self, why: str) -> None:
        self.failure = why
        log.error("scripted run failed: %s", why)
        self.timer.stop()
        self.window.close()

    def _request(self, tag: str, fn: Any, *args: Any, **kwargs: Any) -> None:
        self._pending = tag
        self.window.requests.call(tag, fn, *args, **kwargs)

    def _reply(self, tag: str, result: Any, error: str) -> None:
        if tag != self._pending:
            return
        self._pending = None
        if tag == "script:save-calibration":
            if error:
                return self._fail(f"calibration record not saved: {error}")
            self.calibration_saved = result
            log.info("calibration record saved on the gateway: %s", result)
            self._enter("record" if self.take else "run")
        elif tag == "script:start":
            if error:
                return self._fail(f"recording {self.take} refused: {error}")
            self.window.bridge.set_latest("recording", result)
            self.window.bridge.note_recording(result)
            self._enter("recording")
        elif tag == "script:stop":
            if error:
                return self._fail(f"stopping {self.take} failed: {error}")
            self.window.bridge.set_latest("recording", result)
            log.info("take %s stopped: %s samples", self.take, result.get("samples_written"))
            self._enter("done")
            self.timer.stop()
            self.window.close()
        elif tag.startswith("script:calibration") and error and "confirm" not in tag:
            self._fail(f"calibration refused: {error}")

    # -- the steps ------------------------------------------------------------------------------------------------
    def _poll(self) -> None:
        if time.monotonic() - self._t_start > self.budget_s:
            return self._fail(f"gave up after {self.budget_s:.0f} s in phase {self.phase!r}"
                              + (f" waiting for {self._pending}" if self._pending else ""))
        if self._pending is not None:
            return
        client = self.window.client
        if client is None:
            return self._fail("not connected to a gateway")
        elapsed = time.monotonic() - self._t_phase
        if self.phase == "calibrate":
            self._calibrate(client, elapsed)
        elif self.phase == "record":
            self._request("script:start", client.start_recording, self.take)
        elif self.phase == "recording" and elapsed >= (self.duration_s or 0.0):
            self._request("script:stop", client.stop_recording)
        elif self.phase == "run" and elapsed >= (self.duration_s or 0.0):
            self.timer.stop()
            self.window.close()

    def _calibrate(self, client: Any, elapsed_s: float) -> None:
        if elapsed_s > self.calibration_timeout_s:
            state = (self.window.bridge.latest("calibration") or {}).get("state") or {}
            return self._fail(f"calibration wizard did not finish in {self.calibration_timeout_s:.0f} s "
                              f"(stuck at step {state.get('step')!r}, phase {state.get('phase')!r})")
        if self.window.wizard is None:
            self.window.open_calibration()
        state = (self.window.bridge.latest("calibration") or {}).get("state") or {}
        step = state.get("step")
        if step == "assign" and not self._assigned:
            self._assigned = True
            self.window.wizard.assign_from_mapping()
        elif step in WAITS_FOR_OPERATOR:
            self.window.wizard.next_button.click()  # the gateway refuses (accepted: false) until the step passes
        elif step == "done":
            self._request("script:save-calibration", client.calibration, "save", **self.save_args())

    def save_args(self) -> dict[str, Any]:
        """Arguments of the gateway's calibration ``save``: a record name (the gateway writes
        ``<records_dir>/<name>.calibration.json``; clients never name paths) — the take's, if any."""
        return {"name": self.take or time.strftime("console-%Y%m%d-%H%M%S"), "subject": "", "take": self.take or ""}
