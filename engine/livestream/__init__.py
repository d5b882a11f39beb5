"""Live skeleton out: synthesised poses streamed to animation tools (docs/imu-import.md, "Live skeleton")."""
from engine.livestream.bvh_server import BvhBroadcastServer, frame_line

__all__ = ["BvhBroadcastServer", "frame_line"]
