"""Shared fixtures: where the real mocap lives, and offscreen Qt by default."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

REPO_ROOT = Path(__file__).resolve().parent.parent


def find_shared_mocap() -> Path | None:
    """The full real-mocap set (../shared/mocap beside the checkout, or $COURTSIDE_MOCAP_DIR).

    The project also ships a few clips in engine/data so the demo and most tests run without it."""
    candidates = [os.environ.get("COURTSIDE_MOCAP_DIR"), REPO_ROOT.parent / "shared" / "mocap", Path("/work/shared/mocap")]
    for candidate in candidates:
        if candidate and (Path(candidate) / "README.md").is_file():
            return Path(candidate)
    return None


@pytest.fixture(scope="session")
def shared_mocap() -> Path:
    path = find_shared_mocap()
    if path is None:
        pytest.skip("the shared real-mocap set is not present (set COURTSIDE_MOCAP_DIR)")
    return path
