"""What the console says about each athlete's synthesis: engine, database, channels, lag, rate, cost, confidence,
and the faults in their own list (Qt-free, so the wording is testable with a stub synthesizer).

Why apart from the status bar: one status line held the gateway's figures and every athlete's; at any window
width the second athlete and any error were cut off (issue 30). Each athlete now gets its own block
(`gui.widgets.athlete_status`), its faults in red on a line of their own."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class AthleteStatus:
    """One athlete's synthesis, as shown: ``summary`` (engine and how it runs), ``notes`` (worth knowing) and
    ``faults`` (the operator must act or know the poses are not live)."""

    name: str
    summary: str
    notes: tuple[str, ...] = ()
    faults: tuple[str, ...] = ()


def streamed_summary(stats: Any) -> str:
    """The channels the frames pushed so far carried, e.g. ``streamed acc+orientation+gyro``; beside the engine
    label, which ends with the channels the engine uses (`EngineSpec.label`), an operator sees at once that
    orientations arrive and whether this engine listens to them."""
    streamed = ["acc"] + [name for name, frames in (("orientation", stats.frames_with_orientation),
                                                     ("gyro", stats.frames_with_gyro)) if frames]
    return f"streamed {'+'.join(streamed)}"


def athlete_status(name: str, synthesizer: Any) -> AthleteStatus:
    """The status of one athlete's synthesizer (`gui.synthesis_process.Synthesizer`). A synthesizer that is not
    running (its process died, a restart is under way or was given up) shows no rate or confidence: the dead
    child's last figures would read as live."""
    s = synthesizer.stats
    engine = synthesizer.setup.engine
    pose = synthesizer.latest_pose()
    running = synthesizer.is_alive()
    parts = [engine.label, streamed_summary(s)]
    if engine.lag_applies:
        parts.append(f"lag {s.lag_s:.2f} s")
    if running:
        parts.append(f"{s.frames_per_s:.0f} frames/s, {s.push_ms:.1f} ms/frame")
        if pose is not None and pose.confidence is not None:
            parts.append(f"confidence {pose.confidence:.2f}")
    else:
        parts.append("not running")
    notes = [s.engine_status] if s.engine_status else []
    if s.frames_invalid:
        notes.append(f"{s.frames_invalid} frames without a sensor")
    if s.late_samples or s.late_fixes:
        notes.append(f"{s.late_samples} samples / {s.late_fixes} camera fixes came after their frames")
    faults = [text for text in (synthesizer.fault, s.error and f"ERROR {s.error}",
                                s.falling_behind(engine.rate_hz)) if text]
    return AthleteStatus(name, " · ".join(parts), tuple(notes), tuple(faults))
