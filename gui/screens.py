"""Screenshots of the console's views (for `--screenshots`, scripts/screenshots.py and docs/screenshots/)."""
from __future__ import annotations

from pathlib import Path

from gui.app import pump, save_grab


def capture_console(window, out_dir: Path, prefix: str = "") -> list[Path]:
    """Main view with traces, then the device panel, each after a short settle so the tick has redrawn."""
    out_dir = Path(out_dir)
    paths = []
    for index, name in ((0, "main"), (1, "devices")):
        window.tabs.setCurrentIndex(index)
        pump(0.4)
        paths.append(save_grab(window, out_dir / f"{prefix}{name}.png"))
    window.tabs.setCurrentIndex(0)
    return paths
