"""The console's `--stream-bvh`: its synthesis setup with every emitted pose also sent to animation tools.

Kept here (engine side, no Qt) so gui/cli.py only swaps the setup: the console's worker thread builds its
synthesizer through ``make_synthesizer(lag_s)``; the wrapped factory returns a :class:`StreamingSynthesizer`."""
from __future__ import annotations

from dataclasses import replace
from typing import Any

from engine.livestream.poses import PoseStreamer, StreamingSynthesizer
from engine.livestream.stream_cli import open_stream


def streaming_setup(setup: Any, graph: Any, skeleton: Any, address: str) -> Any:
    """``setup`` (gui.synthesis.SynthesisSetup) whose synthesizers stream their poses on ``address``; live
    samples already arrive in real time, so no pacing."""
    server = open_stream(address, 0.0, "console")
    streamer = PoseStreamer(graph, skeleton, server, realtime=False)
    make = setup.make_synthesizer
    return replace(setup, make_synthesizer=lambda lag_s: StreamingSynthesizer(make(lag_s), streamer))
