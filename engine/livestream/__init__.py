"""Live skeleton out: synthesised poses streamed to animation tools (docs/imu-import.md, "Live skeleton")."""
from engine.livestream.bvh_server import BvhBroadcastServer, frame_line
from engine.livestream.poses import PoseStreamer, StreamingSynthesizer

__all__ = ["BvhBroadcastServer", "PoseStreamer", "StreamingSynthesizer", "frame_line"]
