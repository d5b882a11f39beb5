"""Crash-safe recording of every stream, plus a reader that survives truncation and exporters (npz, CSV).

File layout (``<record_dir>/<take>/take.csrec``), all integers big-endian::

    file header:  b"CSREC\\x00\\x01\\n" | u32 meta_len | meta JSON (UTF-8) | u32 crc32(meta JSON)
    chunk (repeated): b"CHNK" | u32 body_len | u32 crc32(body) | body (a `gateway.codec` body)

Why this shape: the file is append-only, each chunk is self-checking, so a file cut anywhere (kill -9, power
loss) is still readable up to the last intact chunk; a reader never needs an index or footer.

fsync policy: the writer thread wakes every ``flush_interval_s`` (default 0.25 s), concatenates what arrived per
stream into one chunk each, writes them and calls ``os.fsync``. A crash therefore loses at most the last
~0.25 s that was still in memory, never anything already acknowledged as written, and never corrupts earlier data.

Raw samples are never dropped: `Recorder.put` appends to an unbounded in-memory list that only the writer thread
drains (the display path in `gateway.server` is separate and may drop). Backlog size is reported in `state()`.
"""
from __future__ import annotations

import csv
import json
import logging
import os
import re
import struct
import threading
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gateway import codec
from gateway.clock import realign_offline

log = logging.getLogger(__name__)

FILE_MAGIC = b"CSREC\x00\x01\n"
CHUNK_MAGIC = b"CHNK"
_U32 = struct.Struct(">I")
_CHUNK_HEAD = struct.Struct(">4sII")
TAKE_NAME = re.compile(r"^[A-Za-z0-9_.-]{1,100}$")
RECORDING_FILE = "take.csrec"


class RecordingError(ValueError):
    """A recording file that cannot be read at all (names the file and the problem)."""

    def __init__(self, path: Path | str, problem: str):
        super().__init__(f"{path}: {problem}")
        self.path = Path(path)
        self.problem = problem


# ---------------------------------------------------------------------------------------------------- writing
class ChunkFile:
    """Append-only chunk file writer (single writer thread)."""

    def __init__(self, path: Path, meta: dict[str, Any]):
        self.path = Path(path)
        self._fh = open(self.path, "xb")  # never overwrite an earlier take
        meta_bytes = json.dumps(meta, separators=(",", ":")).encode("utf-8")
        self._fh.write(FILE_MAGIC + _U32.pack(len(meta_bytes)) + meta_bytes + _U32.pack(zlib.crc32(meta_bytes)))
        self.sync()
        self.bytes_written = self._fh.tell()
        self.chunks_written = 0

    def append(self, body: bytes) -> None:
        self._fh.write(_CHUNK_HEAD.pack(CHUNK_MAGIC, len(body), zlib.crc32(body)) + body)
        self.bytes_written += _CHUNK_HEAD.size + len(body)
        self.chunks_written += 1

    def sync(self) -> None:
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def close(self) -> None:
        if not self._fh.closed:
            self.sync()
            self._fh.close()


@dataclass
class _Pending:
    """What arrived since the last flush."""

    # (kind, station, sensor) -> row batches of a tabular stream ("samples", "clock_points")
    rows: dict[tuple[str, str, int], list[dict[str, np.ndarray]]] = field(default_factory=dict)
    headers: dict[tuple[str, str, int], dict[str, Any]] = field(default_factory=dict)
    others: list[bytes] = field(default_factory=list)
    n_samples: int = 0


class Recorder:
    """Records one take at a time. Thread-safe `put_*`; a writer thread does all disk I/O."""

    def __init__(self, record_dir: Path | str, flush_interval_s: float = 0.25):
        self.record_dir = Path(record_dir)
        self.flush_interval_s = flush_interval_s
        self._lock = threading.Lock()
        self._pending = _Pending()
        self._file: ChunkFile | None = None
        self._take: str | None = None
        self._started_s = 0.0
        self._samples_written = 0
        self._samples_queued = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last: dict[str, Any] = {"active": False, "take": None}

    @property
    def active(self) -> bool:
        return self._file is not None

    def start(self, take: str, meta: dict[str, Any] | None = None) -> dict[str, Any]:
        """Open ``<record_dir>/<take>/take.csrec`` and start writing. Raises ValueError on a bad/duplicate take."""
        if not TAKE_NAME.match(take):
            raise ValueError(f"take name {take!r} must match {TAKE_NAME.pattern}")
        with self._lock:
            if self._file is not None:
                raise ValueError(f"already recording take {self._take!r}")
            take_dir = self.record_dir / take
            if (take_dir / RECORDING_FILE).exists():
                raise ValueError(f"take {take!r} already exists in {self.record_dir}")
            take_dir.mkdir(parents=True, exist_ok=True)
            self._started_s = time.monotonic()
            full_meta = {"take": take, "started_t_host_s": self._started_s,
                         "started_unix_s": time.time(), "format": "courtside-csrec-1", **(meta or {})}
            self._file = ChunkFile(take_dir / RECORDING_FILE, full_meta)
            self._take = take
            self._pending = _Pending()
            self._samples_written = self._samples_queued = 0
            self._stop.clear()
            self._thread = threading.Thread(target=self._write_loop, name=f"gw-recorder-{take}", daemon=True)
            self._thread.start()
        log.info("recording take %s to %s", take, self._file.path)
        return self.state()

    def put_samples(self, station: str, sensor: int, arrays: dict[str, np.ndarray], header: dict[str, Any] | None = None) -> None:
        """Queue one batch of samples (all arrays share the first dimension). Never blocks on disk."""
        self.put_rows("samples", station, sensor, arrays, header)

    def put_rows(self, kind: str, station: str, sensor: int, arrays: dict[str, np.ndarray],
                 header: dict[str, Any] | None = None) -> None:
        """Queue rows of a tabular stream; rows of one (kind, station, sensor) are merged into one chunk per flush."""
        with self._lock:
            if self._file is None:
                return
            key = (kind, station, int(sensor))
            self._pending.rows.setdefault(key, []).append(arrays)
            if header:
                self._pending.headers[key] = header
            if kind == "samples":
                n = len(next(iter(arrays.values())))
                self._pending.n_samples += n
                self._samples_queued += n

    def put(self, kind: str, header: dict[str, Any], arrays: dict[str, np.ndarray] | None = None) -> None:
        """Queue any other message (camera, event, clock, station hello...) verbatim."""
        body = codec.encode(kind, {"t_host_s": time.monotonic(), **header}, arrays)
        with self._lock:
            if self._file is not None:
                self._pending.others.append(body)

    def _write_loop(self) -> None:
        while not self._stop.wait(self.flush_interval_s):
            self._flush()
        self._flush()

    def _flush(self) -> None:
        with self._lock:
            pending, self._pending = self._pending, _Pending()
            chunk_file = self._file
        if chunk_file is None:
            return
        bodies = list(pending.others)
        for (kind, station, sensor), batches in pending.rows.items():
            arrays = {name: np.concatenate([b[name] for b in batches]) for name in batches[0]}
            header = {**pending.headers.get((kind, station, sensor), {}), "station": station, "sensor": sensor}
            bodies.append(codec.encode(kind, header, arrays))
        if not bodies:
            return
        for body in bodies:
            chunk_file.append(body)
        chunk_file.sync()
        with self._lock:
            self._samples_written += pending.n_samples

    def stop(self) -> dict[str, Any]:
        """Flush everything queued, fsync, close. Returns the final state (with ``files``)."""
        with self._lock:
            thread, chunk_file = self._thread, self._file
        if chunk_file is None:
            raise ValueError("not recording")
        self._stop.set()
        if thread is not None:
            thread.join()
        with self._lock:
            state = self.state_locked()
            chunk_file.close()
            self._file = None
            state.update(active=False, files=[str(chunk_file.path)])
            self._last = state
        log.info("recording %s stopped: %d samples", state["take"], state["samples_written"])
        return state

    def state_locked(self) -> dict[str, Any]:
        f = self._file
        if f is None:
            return dict(self._last)
        return {"active": True, "take": self._take, "path": str(f.path), "started_t_host_s": self._started_s,
                "samples_written": self._samples_written, "samples_backlog": self._samples_queued - self._samples_written,
                "chunks_written": f.chunks_written, "bytes_written": f.bytes_written}

    def state(self) -> dict[str, Any]:
        with self._lock:
            return self.state_locked()


# ---------------------------------------------------------------------------------------------------- reading
@dataclass
class RecordingContents:
    """Everything readable from a recording file."""

    path: Path
    meta: dict[str, Any]
    messages: list[codec.Message]
    intact_bytes: int  # bytes up to the end of the last intact chunk
    total_bytes: int
    problem: str | None  # why reading stopped early (None if the file ended cleanly)

    @property
    def truncated(self) -> bool:
        return self.problem is not None


def read_recording(path: Path | str) -> RecordingContents:
    """Read a recording; a torn tail (crash mid-write) is tolerated and reported in ``problem``."""
    path = Path(path)
    if path.is_dir():
        path = path / RECORDING_FILE
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise RecordingError(path, f"cannot read: {exc.strerror or exc}") from exc
    if len(data) < len(FILE_MAGIC) + 4 or not data.startswith(FILE_MAGIC):
        raise RecordingError(path, "not a Courtside recording (bad or missing file magic)")
    (meta_len,) = _U32.unpack_from(data, len(FILE_MAGIC))
    meta_start = len(FILE_MAGIC) + 4
    meta_end = meta_start + meta_len
    if meta_end + 4 > len(data):
        raise RecordingError(path, "file header is truncated (crashed before the first fsync?)")
    meta_bytes = data[meta_start:meta_end]
    if zlib.crc32(meta_bytes) != _U32.unpack_from(data, meta_end)[0]:
        raise RecordingError(path, "file header CRC mismatch")
    meta = json.loads(meta_bytes)
    pos = meta_end + 4
    messages: list[codec.Message] = []
    problem = None
    view = memoryview(data)
    while pos < len(data):
        if pos + _CHUNK_HEAD.size > len(data):
            problem = f"truncated chunk header at byte {pos}"
            break
        magic, body_len, crc = _CHUNK_HEAD.unpack_from(data, pos)
        if magic != CHUNK_MAGIC:
            problem = f"bad chunk magic at byte {pos}"
            break
        body_start = pos + _CHUNK_HEAD.size
        if body_start + body_len > len(data):
            problem = f"truncated chunk body at byte {pos} ({len(data) - body_start} of {body_len} bytes)"
            break
        body = view[body_start : body_start + body_len]
        if zlib.crc32(body) != crc:
            problem = f"chunk CRC mismatch at byte {pos}"
            break
        try:
            messages.append(codec.decode(body))
        except codec.CodecError as exc:
            problem = f"undecodable chunk at byte {pos}: {exc}"
            break
        pos = body_start + body_len
    if problem:
        log.warning("%s: %s; keeping %d intact chunks", path, problem, len(messages))
    return RecordingContents(path, meta, messages, pos, len(data), problem)


@dataclass
class Take:
    """A recording reassembled per stream, arrays concatenated in time order:
    ``samples[(station, sensor)][name]``, ``clock_points[station][name]`` (every clock-sync point: ``raw_ticks``,
    ``ticks``, ``epoch``, ``arrival_s``; ``tick_hz`` in ``clock_tick_hz[station]``), other messages in ``others``."""

    meta: dict[str, Any]
    samples: dict[tuple[str, int], dict[str, np.ndarray]]
    clock_points: dict[str, dict[str, np.ndarray]]
    clock_tick_hz: dict[str, float]
    others: list[codec.Message]
    problem: str | None


def _concatenate(msgs: list[codec.Message]) -> dict[str, np.ndarray]:
    return {name: np.concatenate([m.arrays[name] for m in msgs]) for name in msgs[0].arrays}


def load_take(path: Path | str) -> Take:
    contents = read_recording(path)
    samples: dict[tuple[str, int], list[codec.Message]] = {}
    points: dict[str, list[codec.Message]] = {}
    others = []
    for msg in contents.messages:
        if msg.kind == "samples":
            samples.setdefault((msg.header["station"], int(msg.header["sensor"])), []).append(msg)
        elif msg.kind == "clock_points":
            points.setdefault(msg.header["station"], []).append(msg)
        else:
            others.append(msg)
    return Take(
        contents.meta,
        {key: _concatenate(msgs) for key, msgs in sorted(samples.items())},
        {station: _concatenate(msgs) for station, msgs in sorted(points.items())},
        {station: float(msgs[-1].header["tick_hz"]) for station, msgs in points.items()},
        others, contents.problem,
    )


def realign_take(take: Take, window_s: float = 60.0) -> dict[tuple[str, int], np.ndarray]:
    """Offline clock re-fit of every sample from the recorded clock-sync points (`gateway.clock.realign_offline`,
    centred windows, no warm-up). Samples of a clock epoch with fewer than 10 points keep their online time."""
    out = {}
    for (station, sensor), cols in take.samples.items():
        t = np.array(cols["t_host_s"], dtype=np.float64)
        points = take.clock_points.get(station)
        if points is not None:
            tick_hz = take.clock_tick_hz[station]
            for epoch in np.unique(cols["epoch"]):
                mine = points["epoch"] == epoch
                rows = cols["epoch"] == epoch
                if mine.sum() >= 10:
                    t[rows] = realign_offline(points["ticks"][mine] / tick_hz, points["arrival_s"][mine],
                                              cols["ticks"][rows] / tick_hz, window_s=window_s)
        out[(station, sensor)] = t
    return out


def export_npz(path: Path | str, out: Path | str) -> Path:
    """One npz: ``<station>/<sensor>/<array>`` keys for samples (plus ``t_realigned_s``, the offline clock re-fit),
    ``meta`` and ``messages`` as JSON strings."""
    take = load_take(path)
    realigned = realign_take(take)
    arrays: dict[str, Any] = {}
    for (station, sensor), cols in take.samples.items():
        for name, value in {**cols, "t_realigned_s": realigned[(station, sensor)]}.items():
            arrays[f"{station}/{sensor}/{name}"] = value
    arrays["meta"] = np.array(json.dumps(take.meta))
    arrays["messages"] = np.array(json.dumps([{"kind": m.kind, **m.header} for m in take.others]))
    out = Path(out)
    np.savez_compressed(out, **arrays)
    return out


def export_csv(path: Path | str, out_dir: Path | str) -> list[Path]:
    """One CSV per sensor (``<station>_<sensor>.csv``: one row per sample, vector arrays split into columns, plus
    ``t_realigned_s``) and ``messages.csv`` (t_host_s, kind, JSON header) for everything else."""
    take = load_take(path)
    realigned = realign_take(take)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for (station, sensor), cols in take.samples.items():
        names, columns = [], []
        for name, value in {**cols, "t_realigned_s": realigned[(station, sensor)]}.items():
            value = value.reshape(len(value), -1)
            if value.shape[1] == 1:
                names.append(name)
            else:
                suffixes = "xyz" if value.shape[1] == 3 else [str(i) for i in range(value.shape[1])]
                names.extend(f"{name}_{suffix}" for suffix in suffixes)
            columns.append(value.astype(np.float64))  # exact for u32 counters and ticks < 2**53
        file = out_dir / f"{station}_{sensor}.csv"
        np.savetxt(file, np.hstack(columns), fmt="%.17g", delimiter=",", header=",".join(names), comments="")
        written.append(file)
    file = out_dir / "messages.csv"
    with open(file, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["t_host_s", "kind", "header_json"])
        for m in take.others:
            writer.writerow([m.header.get("t_host_s"), m.kind, json.dumps(m.header)])
    written.append(file)
    return written
