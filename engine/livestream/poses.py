"""Poses as they leave the fixed-lag synthesizer -> BVH frames on a live stream.

Why the raw node pose: the written BVH blends transitions and fixes foot skate over the whole path, which needs
poses that have not been emitted yet; a live tool wants each pose the moment the decoder commits to it. So the
stream carries the graph node's pose placed at its ground position and heading (`engine.graph.postprocess.
place_path`), the same pose the console's skeleton view draws."""
from __future__ import annotations

import time
from typing import Any

import numpy as np

from engine.graph.postprocess import place_path
from engine.livestream.bvh_server import BvhBroadcastServer
from engine.mocap import Motion
from engine.mocap.bvh import bvh_frame_values


class PoseStreamer:
    """Sends emitted poses (``EmittedPose``: node, ground_m, heading_rad) of ``graph`` as BVH frames of ``skeleton``
    (the graph's, whose BVH the client loaded), optionally paced at the graph rate (a recorded take shown live)."""

    def __init__(self, graph: Any, skeleton: Any, server: BvhBroadcastServer, realtime: bool = False) -> None:
        self.graph, self.skeleton, self.server = graph, skeleton, server
        self.fps = float(graph.config.fps)
        self.realtime = realtime
        self._start: float | None = None
        self._sent = 0

    def send(self, poses: list) -> None:
        if not poses:
            return
        nodes = np.array([p.node for p in poses])
        ground = np.array([p.ground_m for p in poses])
        heading = np.array([p.heading_rad for p in poses])
        root, rots = place_path(self.graph, nodes, ground, heading)
        for row in bvh_frame_values(Motion(self.skeleton, self.fps, root, rots)):
            if self.realtime:
                self._start = time.monotonic() if self._start is None else self._start
                delay = self._start + self._sent / self.fps - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            self.server.send_frame(row)
            self._sent += 1


class StreamingSynthesizer:
    """A synthesizer (``push``/``flush`` returning emitted poses) whose emitted poses also go to a
    :class:`PoseStreamer`; everything else is delegated, so it drops in wherever the synthesizer was."""

    def __init__(self, inner: Any, streamer: PoseStreamer) -> None:
        self._inner = inner
        self._streamer = streamer

    def push(self, *args: Any, **kwargs: Any) -> list:
        poses = self._inner.push(*args, **kwargs)
        self._streamer.send(poses)
        return poses

    def flush(self) -> list:
        poses = self._inner.flush()
        self._streamer.send(poses)
        return poses

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)
