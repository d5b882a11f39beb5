"""The one sample -> frame -> pose path shared by live synthesis (the console's worker) and offline synthesis
(`courtside synthesize`): `frames` (resampling onto the frame clock, dropout marking), `camera` (the camera track
aligned to frames), `session` (`StreamSynthesis`), `engines` (which engine/database, checked against the sensors),
`databases` (the default databases from the shipped clips, cached, and the choice of engine), `poses_file` (the
saved poses both sides write, so they can be compared)."""
from .camera import CameraTrack
from .engines import ENGINE_NAMES, EngineMismatchError, EngineSpec, check_live_sensors, default_engine
from .frames import FrameBatch, FrameResampler, box_mean, frame_at_or_after, resample_uniform, window_covered
from .session import (TAKE_START_MARGIN_S, FramePose, OnlineEngine, RecordedStreams, StreamSynthesis,
                      synthesize_streams, take_start_s)

__all__ = ["CameraTrack", "ENGINE_NAMES", "EngineMismatchError", "EngineSpec", "FrameBatch", "FramePose",
           "FrameResampler", "OnlineEngine", "RecordedStreams", "StreamSynthesis", "TAKE_START_MARGIN_S", "box_mean",
           "check_live_sensors", "default_engine", "frame_at_or_after", "resample_uniform", "synthesize_streams",
           "take_start_s", "window_covered"]
