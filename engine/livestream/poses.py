"""Poses as they leave the fixed-lag synthesizer -> BVH frames on a live stream.

Why the raw node pose: the written BVH blends transitions and fixes foot skate over the whole path, which needs
poses that have not been emitted yet; a live tool wants each pose the moment the decoder commits to it. So the
stream carries the graph node's pose placed at its ground position and heading (`engine.graph.postprocess.
place_path`), the same pose the console's skeleton view draws."""
from __future__ import annotations

import time
from typing import Any

import numpy as np

from engine.graph.postprocess import place_blend, place_path
from engine.mocap import Motion


class PoseStreamer:
    """Sends emitted poses (``EmittedPose``: node, ground_m, heading_rad) of ``graph`` as frames of ``skeleton``
    (the graph's) to every output (anything with ``send_motion(motion)``: `BvhBroadcastServer`,
    `engine.livestream.vmc.VmcSender`), optionally paced at the graph rate (a recorded take shown live)."""

    def __init__(self, graph: Any, skeleton: Any, outputs: Any, realtime: bool = False) -> None:
        self.graph, self.skeleton = graph, skeleton
        self.outputs = list(outputs) if isinstance(outputs, (list, tuple)) else [outputs]
        self.fps = float(graph.config.fps)
        self.realtime = realtime
        self._start: float | None = None
        self._sent = 0

    @property
    def server(self) -> Any:
        """The first output (the BVH server when there is one)."""
        return self.outputs[0]

    def send(self, poses: list) -> None:
        if not poses:
            return
        nodes = np.array([p.node for p in poses])
        ground = np.array([p.ground_m for p in poses])
        heading = np.array([p.heading_rad for p in poses])
        blend = [p.blend_nodes for p in poses]
        root, rots = place_path(self.graph, nodes, ground, heading) if blend[0] is None else \
            place_blend(self.graph, np.stack(blend), ground, heading)  # the search's blended pose (blend_paths)
        motion = Motion(self.skeleton, self.fps, root, rots)
        for f in range(motion.n_frames):
            if self.realtime:
                self._start = time.monotonic() if self._start is None else self._start
                delay = self._start + self._sent / self.fps - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            frame = motion.slice(f, f + 1)
            for output in self.outputs:
                output.send_motion(frame)
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
