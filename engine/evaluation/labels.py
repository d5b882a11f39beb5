"""Content and style of a database clip, so protocols can hold out every clip of one content (or style).

The Bandai Namco sets keep a JSON `{content, style}` beside each BVH whose integers index
`cfg/content_label.txt` / `cfg/style_label.txt` (lines like `dataset-1_walk-left`). We read that when it is
there and fall back to the file name (`dataset-1_<content>_<style>_<id>`), else the file stem (every clip its
own content). Neither Bandai set names its performers, so there is no per-performer label to read.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from engine.errors import MalformedFileError
from engine.safe_load import read_json

_BANDAI = re.compile(r"dataset-\d+_(?P<content>[a-z-]+)_(?P<style>[a-z-]+)_\d+$")


@dataclass(frozen=True)
class ClipLabel:
    content: str
    style: str


def _label_table(cfg_file: Path) -> list[str]:
    """Names of a Bandai cfg label list, with the `dataset-N_` prefix removed."""
    return [line.strip().split("_", 1)[-1] for line in cfg_file.read_text().splitlines() if line.strip()]


def clip_label(path: str | Path) -> ClipLabel:
    """Content/style of one clip file (see module doc)."""
    path = Path(path)
    sidecar = path.with_suffix(".json")
    cfg = path.parent.parent / "cfg"
    if sidecar.is_file() and (cfg / "content_label.txt").is_file() and (cfg / "style_label.txt").is_file():
        try:
            raw = read_json(sidecar)
            content = _label_table(cfg / "content_label.txt")[int(raw["content"])]
            style = _label_table(cfg / "style_label.txt")[int(raw["style"])]
        except (ValueError, KeyError, IndexError, TypeError) as exc:
            raise MalformedFileError(sidecar, None, f"not a Bandai label {{content, style}} ({exc})") from exc
        return ClipLabel(content, style)
    m = _BANDAI.match(path.stem)
    if m:
        return ClipLabel(m.group("content"), m.group("style"))
    return ClipLabel(path.stem, "")
