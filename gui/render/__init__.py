"""Qt-free 3-D rendering for the console: camera maths, court geometry, and a moderngl skeleton renderer.

Kept free of Qt so it can be tested (and benchmarked) headless with an EGL context alone."""
