"""Where a stream's samples came from, so a bad sample is reported by file and line (or sample) and not as an
anonymous array index (issue 30: every refusal names the file and, when it can, the line)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.errors import CourtsideError, MalformedFileError


@dataclass(frozen=True)
class Origin:
    """The file a stream was read from and, for text tables, each sample's 1-based file line (None for formats
    without lines, e.g. MVNX frames, where the sample index is named instead)."""

    path: Path
    lines: np.ndarray | None = None

    def error(self, sample: int | None, problem: str) -> MalformedFileError:
        """A refusal of ``sample`` (None: the whole stream) of this file."""
        if sample is None:
            return MalformedFileError(self.path, None, problem)
        if self.lines is not None:
            return MalformedFileError(self.path, int(self.lines[sample]), problem)
        return MalformedFileError(self.path, None, f"sample {sample}: {problem}")

    def subset(self, index: np.ndarray) -> "Origin":
        """The origin of the samples ``index`` (a reader that keeps or reorders rows keeps their lines)."""
        return Origin(self.path, None if self.lines is None else self.lines[index])


def stream_error(origin: Origin | None, label: str, sample: int | None, problem: str) -> CourtsideError:
    """A refusal naming the file and line when the stream has an origin, else the sensor label alone (streams
    built in code, e.g. by tests or the benches)."""
    text = f"sensor {label!r}: {problem}"
    if origin is None:
        return CourtsideError(text if sample is None else f"sensor {label!r}, sample {sample}: {problem}")
    return origin.error(sample, text)
