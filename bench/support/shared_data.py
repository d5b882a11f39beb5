"""Where the shared real-mocap set lives, for the tests' `shared_mocap` fixture and the benches' defaults."""
from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]


def find_shared_mocap() -> Path | None:
    """The full real-mocap set (../shared/mocap beside the checkout, or $COURTSIDE_MOCAP_DIR).

    The project also ships a few clips in engine/data so the demo and most tests run without it."""
    candidates = [os.environ.get("COURTSIDE_MOCAP_DIR"), REPO_ROOT.parent / "shared" / "mocap", Path("/work/shared/mocap")]
    for candidate in candidates:
        if candidate and (Path(candidate) / "README.md").is_file():
            return Path(candidate)
    return None
