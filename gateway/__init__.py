"""Headless gateway daemon: base-station readers, one clock, camera, calibration, recording, streaming.

Must never import `gui` (it runs on a small board without Qt or OpenGL)."""
