"""The console's `--stream-bvh`: its synthesis engine with every emitted pose also sent to animation tools.

Kept here (engine side, no Qt) so gui/cli.py only swaps the engine: the console's worker builds its engine
through ``EngineSpec.make(lag_s)``; the wrapped factory returns a :class:`StreamingSynthesizer`."""
from __future__ import annotations

from dataclasses import replace

from engine.errors import CourtsideError
from engine.livestream.poses import PoseStreamer, StreamingSynthesizer
from engine.livestream.stream_cli import open_stream
from engine.stream.engines import EngineSpec


def streaming_engine(spec: EngineSpec, address: str) -> EngineSpec:
    """``spec`` whose engines also stream their poses on ``address``; live samples already arrive in real time, so
    no pacing. Poses are placed on the motion graph's path, so only that engine streams."""
    if spec.graph is None or spec.skeleton is None:
        raise CourtsideError(f"--stream-bvh streams the motion graph's poses; the {spec.name} engine has none")
    server = open_stream(address, 0.0, "console")
    streamer = PoseStreamer(spec.graph, spec.skeleton, server, realtime=False)
    return replace(spec, make=lambda lag_s: StreamingSynthesizer(spec.make(lag_s), streamer))
