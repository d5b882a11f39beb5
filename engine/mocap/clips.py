"""Finding and loading clips: the sample shipped in engine/data, single files by extension, and whole
databases resampled to the graph rate (with an on-disk cache of the parsed arrays)."""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

from engine import progress
from engine.errors import MalformedFileError
from engine.mocap.asf_amc import AsfSkeleton, read_amc, read_asf
from engine.mocap.bvh import read_bvh
from engine.mocap.skeleton import Motion, Skeleton
from engine.mocap.transform import resample

DATA_DIR = Path(__file__).resolve().parent.parent / "data" / "mocap"
CACHE_VERSION = 1


def sample_clips() -> dict[str, Path]:
    """{clip name: path} of the CMU clips shipped in engine/data/mocap (see its README for content)."""
    return {p.stem: p for p in sorted((DATA_DIR / "cmu").glob("*.amc"))}


def _sibling_asf(amc: Path) -> Path:
    """The ASF for an AMC: `<subject>.asf` (CMU naming `16_15.amc` -> `16.asf`) or the only .asf beside it."""
    subject = amc.parent / (amc.stem.split("_")[0] + ".asf")
    if subject.is_file():
        return subject
    found = sorted(amc.parent.glob("*.asf"))
    if len(found) == 1:
        return found[0]
    raise MalformedFileError(amc, None, f"cannot tell which ASF skeleton goes with it ({len(found)} .asf files beside it)")


_asf_cache: dict[tuple[Path, int, int], AsfSkeleton] = {}  # (path, size, mtime): clips of a subject share one ASF


def load_clip(path: str | Path, fps: float | None = None) -> Motion:
    """Load a .bvh, or an .amc with its sibling .asf; optionally resample to `fps`."""
    path = Path(path)
    if not path.is_file():
        raise MalformedFileError(path, None, "no such file")
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        motion = read_bvh(path)
    elif suffix == ".amc":
        asf_path = _sibling_asf(path).resolve()
        stat = asf_path.stat()
        key = (asf_path, stat.st_size, stat.st_mtime_ns)
        if key not in _asf_cache:
            _asf_cache[key] = read_asf(asf_path)
        motion = read_amc(path, _asf_cache[key])
    else:
        raise MalformedFileError(path, None, f"unsupported clip type {suffix!r} (expected .bvh or .amc)")
    return resample(motion, fps) if fps is not None else motion


def default_cache_dir() -> Path:
    """$COURTSIDE_CACHE_DIR, else $XDG_CACHE_HOME/courtside/mocap, else ~/.cache/courtside/mocap."""
    if os.environ.get("COURTSIDE_CACHE_DIR"):
        return Path(os.environ["COURTSIDE_CACHE_DIR"]) / "mocap"
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "courtside" / "mocap"


def _cache_key(path: Path, fps: float) -> str:
    stat = path.stat()
    text = f"{CACHE_VERSION}|{path.resolve()}|{stat.st_size}|{stat.st_mtime_ns}|{fps}"
    return hashlib.sha1(text.encode()).hexdigest()


def _save(file: Path, motion: Motion) -> None:
    s = motion.skeleton
    file.parent.mkdir(parents=True, exist_ok=True)
    tmp = file.with_suffix(".tmp.npz")
    np.savez(tmp, names=np.array(s.names), parents=s.parents, offsets_m=s.offsets_m, end_site=s.end_site,
             fps=motion.fps, root_positions_m=motion.root_positions_m, rotations=motion.rotations,
             name=np.array(motion.name))
    tmp.replace(file)


def _load(file: Path) -> Motion:
    with np.load(file) as z:
        skel = Skeleton(tuple(str(n) for n in z["names"]), z["parents"], z["offsets_m"], z["end_site"])
        return Motion(skel, float(z["fps"]), z["root_positions_m"], z["rotations"], str(z["name"]))


def load_database(paths: list[str | Path], fps: float = 30.0, cache_dir: str | Path | None = None,
                  use_cache: bool = True) -> list[Motion]:
    """Load many clips resampled to `fps` (the graph rate), in the given order.

    Parsed, resampled clips are cached as .npz keyed by path, size, mtime and fps, because text parsing
    dominates the load time of a large database (numbers in docs/engine-mocap.md)."""
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    out = []
    for p in progress.bar(list(map(Path, paths)), desc="loading clips", unit="clip"):
        file = cache / f"{_cache_key(p, fps)}.npz" if use_cache else None
        if file is not None and file.is_file():
            try:
                out.append(_load(file))
                continue
            except (OSError, ValueError, KeyError):
                pass  # unreadable cache entry: parse the source again and overwrite it
        motion = load_clip(p, fps)
        if file is not None:
            try:
                _save(file, motion)
            except OSError:
                pass  # a read-only cache must not stop loading
        out.append(motion)
    return out
