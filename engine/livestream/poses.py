"""Decided poses -> BVH frames on a live stream.

Each pose the decoder emits carries its root and local joint rotations (engine.stream.decided): the stream sends
exactly that pose, the one the console's skeleton view draws and the BVH file holds, the moment the decoder
commits to it."""
from __future__ import annotations

import time
from typing import Any

from engine.stream.decided import poses_to_motion


class PoseStreamer:
    """Sends decided poses (anything with ``root_m`` and ``local_rotations``: `EmittedPose`, `EnginePose`) as
    frames of ``skeleton`` at ``fps`` to every output (anything with ``send_motion(motion)``:
    `BvhBroadcastServer`, `engine.livestream.vmc.VmcSender`), optionally paced at that rate (a recorded take shown
    live)."""

    def __init__(self, skeleton: Any, fps: float, outputs: Any, realtime: bool = False) -> None:
        self.skeleton = skeleton
        self.outputs = list(outputs) if isinstance(outputs, (list, tuple)) else [outputs]
        self.fps = float(fps)
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
        motion = poses_to_motion(self.skeleton, self.fps, poses)
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
