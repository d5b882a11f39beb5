"""Error types shared by the engine's file readers.

One exception type for every bad input file, so callers (CLI, gateway, tests) can catch a single class and
still show the user exactly which file, which line and what was wrong with it."""
from __future__ import annotations

from pathlib import Path


class MalformedFileError(ValueError):
    """A data file (BVH, ASF, AMC, C3D, cache...) could not be parsed.

    `line` is the 1-based line number when the problem can be pinned to a line, else None
    (binary formats, or problems that concern the whole file)."""

    def __init__(self, path: str | Path, line: int | None, problem: str) -> None:
        self.path = str(path)
        self.line = line
        self.problem = problem
        where = f"{self.path}, line {line}" if line is not None else self.path
        super().__init__(f"{where}: {problem}")
