"""The live demo: real mocap replayed as body-worn accelerometers on emulated base stations, a synthetic overhead
camera and the gateway (`hardware`), the held-out performance and its ground truth (`performance`), and the
console window on top (`session`). Qt is imported only by `session`."""
from gui.demo.performance import (HELD_OUT_CLIPS, STATION_SENSORS, Performance, TruthClock, build_performance,
                                  placements_for_demo, sensor_segments, synthesis_sensors, truth_from_events)

__all__ = ["HELD_OUT_CLIPS", "STATION_SENSORS", "Performance", "TruthClock", "build_performance",
           "placements_for_demo", "sensor_segments", "synthesis_sensors", "truth_from_events"]
