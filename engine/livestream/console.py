"""The console's `--stream-bvh` / `--stream-vmc`: its synthesis engine with every emitted pose also sent to
animation tools.

Kept here (engine side, no Qt) so gui/cli.py only swaps the engine: the console's worker builds its engine
through ``EngineSpec.make(lag_s)``; the wrapped factory returns a :class:`StreamingSynthesizer`."""
from __future__ import annotations

from dataclasses import replace
from typing import Any

from engine.errors import CourtsideError
from engine.livestream.poses import PoseStreamer, StreamingSynthesizer
from engine.livestream.stream_cli import open_stream, open_vmc
from engine.stream.engines import EngineSpec


def streaming_engine(spec: EngineSpec, bvh: str | None = None, vmc: str | None = None) -> EngineSpec:
    """``spec`` whose engines also stream their poses as BVH over TCP on ``bvh`` and/or as VMC over OSC/UDP to
    ``vmc`` (``[HOST:]PORT`` each); live samples already arrive in real time, so no pacing. The streams carry
    the decided poses themselves (root + local rotations of ``spec.skeleton``), so an engine needs a skeleton."""
    flags = " / ".join(flag for flag, address in (("--stream-bvh", bvh), ("--stream-vmc", vmc)) if address)
    if spec.skeleton is None:
        raise CourtsideError(f"{flags} streams an engine's decided rotations; the {spec.name} engine names no "
                             "skeleton for them")
    outputs: list[Any] = []
    if bvh:
        outputs.append(open_stream(bvh, 0.0, "console"))
    if vmc:
        outputs.append(open_vmc(vmc, spec.skeleton, "console"))
    streamer = PoseStreamer(spec.skeleton, spec.rate_hz, outputs, realtime=False)
    # the BVH server's accept thread and the sockets live in this process: the console keeps this engine here
    return replace(spec, make=lambda lag_s: StreamingSynthesizer(spec.make(lag_s), streamer), in_process=True)
