"""GUI test fixtures: a shared EGL renderer (context creation is the slow part)."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def renderer():
    from gui.render.skeleton_renderer import SkeletonRenderer

    r = SkeletonRenderer(480, 320)
    yield r
    r.release()
