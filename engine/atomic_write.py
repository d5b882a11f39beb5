"""The one way a command writes a result file: never over one of its own inputs, never half-written.

Why (issue 30): ``courtside calibrate t.npz -o t.json`` wrote the record's raw samples to ``t.npz`` (the record
swaps the suffix) and so destroyed the take it had just read; ``import-imu x.csv -o x.csv`` replaced its own
recording; and a write that failed half-way (full disk, a kill) left a truncated take under the final name.

`refuse_overwriting_inputs` compares resolved paths (so ``./t.npz``, an absolute path and a symlink to the input
are all caught) and names both files. `atomic_write` writes to a temporary file in the destination's own
directory (same filesystem, so the rename is atomic), fsyncs it, then `os.replace`s it onto the final name: a
reader sees the old file or the whole new one, and a failure removes the temporary file and leaves the old file
untouched."""
from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import IO

from engine.errors import CourtsideError


def _same_file(a: Path, b: Path) -> bool:
    """Do ``a`` and ``b`` name one file (resolved paths equal, or the same inode when both exist)?"""
    if a.resolve() == b.resolve():
        return True
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def refuse_overwriting_inputs(outputs: Iterable[str | Path], inputs: Iterable[str | Path],
                              what: str = "this output") -> None:
    """Refuse (CourtsideError, before any work) an output path that is one of the input files, naming both;
    ``what`` says what the output is when the user did not name it (e.g. a file written beside the one named).

    An input may be a folder (x-IMU3 recordings, a folder of MT exports): then every file under it counts."""
    inputs = [Path(p) for p in inputs]
    for out in (Path(p) for p in outputs):
        for given in inputs:
            under = [given] + (sorted(p for p in given.rglob("*") if p.is_file()) if given.is_dir() else [])
            hit = next((p for p in under if _same_file(out, p)), None)
            if hit is not None:
                hit_is = "the input file itself" if str(hit) == str(out) else f"the input file {hit}"
                raise CourtsideError(f"{out}: {what} would overwrite {hit_is}; choose another output name")


def _umask() -> int:
    """The process's umask (read by setting it, then setting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write(path: str | Path, write: Callable[[IO[bytes]], None]) -> Path:
    """Call ``write(file)`` on a temporary file beside ``path``, fsync it and rename it to ``path``.

    Errors of the write itself (OSError: disk full, no permission, missing directory) become one CourtsideError
    naming ``path``; whatever happens, the temporary file is removed and an existing ``path`` is unchanged."""
    path = Path(path)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    except OSError as exc:
        raise CourtsideError(f"{path}: cannot write ({exc.strerror or exc})") from None
    tmp = Path(tmp_name)
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes it 0600; the result gets a normal file's mode
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        raise CourtsideError(f"{path}: cannot write ({exc.strerror or exc})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return path
