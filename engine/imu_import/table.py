"""Delimited text tables (CSV/TSV) as a header and a float matrix, with errors that name the file and line.

Why not ``numpy.loadtxt`` directly: device exports carry comment preambles (``//`` in Xsens MT Manager text
exports, ``#`` elsewhere), empty fields and ``NaN`` strings, and a bad row must be reported by its line number
rather than as a numpy traceback."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.errors import MalformedFileError
from engine.imu_import.origin import Origin

COMMENT_PREFIXES = ("//", "#")
_DELIMITERS = ("\t", ",", ";")


@dataclass(frozen=True)
class Table:
    """``header`` (C,) column names, ``values`` (N, C) floats (NaN where a field is empty), the ``preamble``
    comment lines, the 1-based file line of the header and of each data row (for messages)."""

    path: Path
    header: list[str]
    values: np.ndarray
    preamble: list[str]
    header_line: int
    lines: np.ndarray

    def origin(self) -> Origin:
        """Where each row came from (file and line), for the sample checks' messages."""
        return Origin(self.path, self.lines)

    def column(self, name_or_index: str) -> int:
        """Index of a column given by its exact name, or by a 0-based index written as digits."""
        if name_or_index in self.header:
            return self.header.index(name_or_index)
        if name_or_index.isdigit() and int(name_or_index) < len(self.header):
            return int(name_or_index)
        raise MalformedFileError(self.path, self.header_line,
                                 f"no column {name_or_index!r}; columns: {', '.join(self.header)}")

    def get(self, names: list[str] | tuple[str, ...]) -> np.ndarray:
        """Columns (N, len(names)) by name or index."""
        return self.values[:, [self.column(n) for n in names]]


def sniff_delimiter(line: str) -> str:
    """The delimiter that splits the header line into the most fields (tab, comma or semicolon)."""
    return max(_DELIMITERS, key=lambda d: line.count(d))


def read_table(path: str | Path, delimiter: str | None = None) -> Table:
    """Read a header row and numeric rows; comment lines (``//``, ``#``) before the header are the preamble."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8-sig", errors="replace").splitlines()
    except OSError as exc:
        raise MalformedFileError(path, None, f"cannot read: {exc.strerror}") from None
    preamble: list[str] = []
    start = 0
    while start < len(lines) and (not lines[start].strip() or lines[start].lstrip().startswith(COMMENT_PREFIXES)):
        preamble.append(lines[start])
        start += 1
    if start >= len(lines):
        raise MalformedFileError(path, None, "no header row (the file is empty or only comments)")
    delim = delimiter or sniff_delimiter(lines[start])
    header = [h.strip() for h in lines[start].split(delim)]
    row_lines = [i + 1 for i in range(start + 1, len(lines)) if lines[i].strip()]
    rows = [lines[i - 1] for i in row_lines]
    if not rows:
        raise MalformedFileError(path, start + 1, "a header but no data rows")
    fields = [r.split(delim) for r in rows]
    widths = np.array([len(f) for f in fields])
    bad = np.flatnonzero(widths != len(header))
    if len(bad):
        k = int(bad[0])
        raise MalformedFileError(path, row_lines[k], f"{widths[k]} fields, the header has {len(header)}")
    cells = np.array(fields, dtype=object)
    cells[cells == ""] = "nan"
    try:
        values = cells.astype(float)
    except ValueError:
        for k, row in enumerate(fields):
            for name, cell in zip(header, row):
                try:
                    float(cell or "nan")
                except ValueError:
                    raise MalformedFileError(path, row_lines[k], f"column {name!r}: {cell!r} is not a number") \
                        from None
        raise
    return Table(path, header, values, preamble, start + 1, np.array(row_lines))

