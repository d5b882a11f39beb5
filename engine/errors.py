"""The project's error root and its one bad-file error.

Every error the project raises on purpose (bad file, bad argument, bad device field, refused request) derives from
`CourtsideError`, so the `courtside` dispatcher can turn any of them into one line and a non-zero exit the same
way, and a traceback always means a bug. Bad input files raise `MalformedFileError`, which names the file, the
location when known, and the problem. `engine` is pure numpy/scipy, so gateway and firmware code can import this
module without pulling in anything heavy."""
from __future__ import annotations

from pathlib import Path


class CourtsideError(Exception):
    """Root of every deliberate Courtside error: the message is the whole user-facing explanation."""


class MalformedFileError(CourtsideError, ValueError):
    """A data file (BVH, ASF, AMC, C3D, cache...) could not be parsed.

    `line` is the 1-based line number when the problem can be pinned to a line, else None
    (binary formats, or problems that concern the whole file)."""

    def __init__(self, path: str | Path, line: int | None, problem: str) -> None:
        self.path = str(path)
        self.line = line
        self.problem = problem
        where = f"{self.path}, line {line}" if line is not None else self.path
        super().__init__(f"{where}: {problem}")
