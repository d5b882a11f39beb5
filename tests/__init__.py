"""Test suite: real serial over ptys, real sockets, real Qt widgets offscreen, real OpenGL via EGL."""
