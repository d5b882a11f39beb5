"""Checks of arrays read from a file against the shapes and kinds the reader expects, so a file that parses but
holds the wrong arrays is refused at load with one line naming the file, the array and the problem — not a
traceback from deep inside the code that uses it (IndexError, TypeError, a division by zero).

A spec maps each array name to (kind, dims): kind ``"f"`` finite real numbers, ``"i"`` integers, ``"b"`` bools,
``"U"`` strings; dims are ints, or symbols (``"N"``) that must agree across arrays, or a symbol times an int
(``"S*3"``). `check_arrays` returns the symbols' values, for the range checks only the reader knows."""
from __future__ import annotations

import zipfile
import zlib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .errors import MalformedFileError

# everything numpy raises reading a file that is not what it should be: missing or unreadable, empty (EOFError),
# a broken zip or member (BadZipFile, zlib.error), a pickle or a bad header (ValueError)
READ_ERRORS = (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error)


def load_npz(path: str | Path, what: str) -> dict[str, np.ndarray]:
    """Every array of an .npz (no pickle), read now; a file that cannot be read as one is refused: "cannot read
    <what> (<why>)"."""
    try:
        npz = np.load(path, allow_pickle=False)
        if not isinstance(npz, np.lib.npyio.NpzFile):
            raise ValueError("a single array, not an .npz archive")
        with npz:
            return {key: npz[key] for key in npz.files}
    except READ_ERRORS as exc:
        raise MalformedFileError(path, None, f"cannot read {what} ({exc})") from None


def load_npy(path: str | Path, what: str) -> np.ndarray:
    """One array saved with numpy.save (no pickle); anything else is refused: "cannot read <what> (<why>)"."""
    try:
        value = np.load(path, allow_pickle=False)
    except READ_ERRORS as exc:
        raise MalformedFileError(path, None, f"cannot read {what} ({exc})") from None
    if not isinstance(value, np.ndarray):
        value.close()
        raise MalformedFileError(path, None, f"cannot read {what} (an .npz archive, not one array)")
    return value

KINDS = {"f": ("real numbers", "fiu"), "i": ("integers", "iu"), "b": ("booleans", "b"), "U": ("strings", "U")}


def _dim(symbol: str | int, sizes: dict[str, int], actual: int) -> bool:
    """Does ``actual`` fit ``symbol``? A first sight of a symbol binds it."""
    if isinstance(symbol, int):
        return actual == symbol
    name, _, times = symbol.partition("*")
    k = int(times or 1)
    if actual % k:
        return False
    sizes.setdefault(name, actual // k)
    return sizes[name] * k == actual


def check_arrays(path: str | Path, arrays: Mapping[str, np.ndarray],
                 spec: Mapping[str, tuple[str, tuple[str | int, ...]]]) -> dict[str, int]:
    """Refuse (MalformedFileError) a missing array, a wrong kind, a wrong shape, or a non-finite number; returns
    the symbol sizes."""
    sizes: dict[str, int] = {}
    bound_by: dict[str, str] = {}  # symbol -> the array that fixed it (named when another disagrees)
    for key, (kind, dims) in spec.items():
        if key not in arrays:
            raise MalformedFileError(path, None, f"no '{key}' array")
        value = np.asarray(arrays[key])
        what, dtype_kinds = KINDS[kind]
        if value.dtype.kind not in dtype_kinds:
            raise MalformedFileError(path, None, f"'{key}' holds {value.dtype} values, expected {what}")
        if value.ndim != len(dims) or not all(_dim(d, sizes, n) for d, n in zip(dims, value.shape)):
            known = [f"{n} = {sizes[n]} from '{bound_by[n]}'" for n in dict.fromkeys(
                str(d).partition("*")[0] for d in dims) if n in bound_by]
            shown = "(" + ", ".join(str(d) for d in dims) + ("," if len(dims) == 1 else "") + ")"
            raise MalformedFileError(path, None, f"'{key}' has shape {value.shape}, expected {shown}"
                                                 + (f" ({', '.join(known)})" if known else ""))
        for d in dims:
            if isinstance(d, str):
                bound_by.setdefault(d.partition("*")[0], key)
        if kind == "f" and not np.isfinite(value).all():
            raise MalformedFileError(path, None, f"'{key}' holds NaN or infinite values")
    return sizes


def check_index_range(path: str | Path, name: str, values: np.ndarray, low: int, high: int) -> None:
    """Refuse indices outside [low, high)."""
    values = np.asarray(values)
    if values.size and (values.min() < low or values.max() >= high):
        raise MalformedFileError(path, None, f"'{name}' indices must lie in [{low}, {high}), "
                                             f"found {values.min()}..{values.max()}")
