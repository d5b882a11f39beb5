"""`courtside synthesize --stream-bvh [HOST:]PORT`: the synthesised frames to live animation tools."""
from __future__ import annotations

import sys

from engine.errors import CourtsideError
from engine.livestream.bvh_server import BvhBroadcastServer
from engine.mocap import Motion
from engine.mocap.bvh import bvh_frame_values


def parse_address(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    try:
        return host or "127.0.0.1", int(port)
    except ValueError:
        raise CourtsideError(f"--stream-bvh {text!r}: expected [HOST:]PORT") from None


def stream_motion(motion: Motion, address: str, wait_s: float) -> int:
    """Serve ``motion`` at its own frame rate to the clients that connect within ``wait_s``; frames sent."""
    host, port = parse_address(address)
    with BvhBroadcastServer(host, port) as server:
        print(f"synthesize: BVH stream on {server.address[0]}:{server.address[1]}, waiting up to {wait_s:g} s for a "
              "client", file=sys.stderr)
        if not server.wait_for_clients(1, wait_s):
            print("synthesize: no BVH stream client connected; nothing streamed", file=sys.stderr)
            return 0
        server.stream(bvh_frame_values(motion), motion.fps)
        return server.frames_sent
