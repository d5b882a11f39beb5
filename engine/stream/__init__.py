"""The one sample -> frame -> pose path shared by live synthesis (the console's worker) and offline synthesis
(`courtside synthesize`): `frames` (resampling onto the frame clock, dropout marking), `camera` (the camera track
aligned to frames), `session` (`StreamSynthesis`), `engines` (the engine protocol: `EngineSpec`, `OnlineEngine`,
`drive_frames`, the checks against the live sensors), `registry` (which engines exist: name -> the engine package's adapter), `databases` (the default databases from
the shipped clips and the choice of engine), `poses_file` (the saved poses both sides write, so they can be
compared)."""
from .camera import CameraTrack
from .engines import (EngineMismatchError, EnginePose, EngineSpec, OnlineEngine, check_live_sensors, default_engine,
                      drive_frames)
from .frames import FrameBatch, FrameResampler, box_mean, frame_at_or_after, resample_uniform, window_covered
from .registry import engine_entry, engine_names, register
from .session import (TAKE_START_MARGIN_S, FramePose, RecordedStreams, StreamSynthesis, synthesize_streams,
                      take_start_s)

__all__ = ["CameraTrack", "EngineMismatchError", "EnginePose", "EngineSpec", "FrameBatch", "FramePose",
           "FrameResampler", "OnlineEngine", "RecordedStreams", "StreamSynthesis", "TAKE_START_MARGIN_S", "box_mean",
           "check_live_sensors", "default_engine", "drive_frames", "engine_entry", "engine_names", "frame_at_or_after",
           "register", "resample_uniform", "synthesize_streams", "take_start_s", "window_covered"]
