"""`--stream-bvh` / `--stream-vmc [HOST:]PORT` of `courtside synthesize` and `courtside console`:
synthesised poses to animation tools."""
from __future__ import annotations

import sys
import time
from typing import Any

from engine.errors import CourtsideError
from engine.livestream.bvh_server import BvhBroadcastServer


def parse_address(text: str, flag: str = "--stream-bvh") -> tuple[str, int]:
    host, _, port = str(text).rpartition(":")
    try:
        return host or "127.0.0.1", int(port)
    except ValueError:
        raise CourtsideError(f"{flag} {text!r}: expected [HOST:]PORT") from None


def open_stream(address: str, wait_s: float, who: str = "synthesize") -> BvhBroadcastServer:
    """A broadcast server on ``address`` (loopback unless a host is given) that has waited up to ``wait_s`` for
    its first client (it keeps accepting clients afterwards)."""
    host, port = parse_address(address)
    try:
        server = BvhBroadcastServer(host, port)
    except OSError as exc:
        raise CourtsideError(f"--stream-bvh {address}: cannot listen ({exc.strerror or exc})") from None
    print(f"{who}: BVH stream (Axis Neuron convention) on {server.address[0]}:{server.address[1]}", file=sys.stderr)
    if wait_s > 0 and not server.wait_for_clients(1, wait_s):
        print(f"{who}: no BVH client within {wait_s:g} s; streaming to whoever connects", file=sys.stderr)
    return server


def open_vmc(address: str, skeleton: Any, who: str = "synthesize") -> Any:
    """A VMC sender (OSC over UDP) to ``address`` (127.0.0.1 unless a host is given)."""
    from engine.livestream.vmc import VmcSender

    host, port = parse_address(address, "--stream-vmc")
    print(f"{who}: VMC (OSC/UDP) to {host}:{port}", file=sys.stderr)
    return VmcSender(skeleton, host, port)


def stream_motion(outputs: list[Any], motion: Any) -> None:
    """Every frame of ``motion`` to every output (``send_motion``), paced at the motion's rate."""
    start = time.monotonic()
    for f in range(motion.n_frames):
        delay = start + f / motion.fps - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        frame = motion.slice(f, f + 1)
        for output in outputs:
            output.send_motion(frame)
