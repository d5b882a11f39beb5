"""Crash-safe recording of every stream, plus a reader that survives truncation and damage, and exporters.

File layout (``<record_dir>/<take>/take.csrec``), all integers big-endian::

    file header:  b"CSREC\\x00\\x01\\n" | u32 meta_len | meta JSON (UTF-8) | u32 crc32(meta JSON)
    chunk (repeated): b"CHNK" | u32 body_len | u32 crc32(body) | body (a `gateway.codec` body)

The first chunk (``take_meta``) repeats the header's meta and the last one (``take_end``) is written only when
the take is closed on purpose (stopped, or ended by a disk fault), with the reason and the counts.

Why this shape: the file is append-only and each chunk is self-checking and starts with a magic, so a file cut
anywhere (kill -9, power loss) is readable up to the last intact chunk, and a damaged byte costs only the chunk
it hit: the reader resynchronises on the next chunk whose magic, length and CRC agree and reports the bytes it
skipped. The header copy keeps a take readable when its header is damaged, and the end chunk tells a take that
was closed from one whose writer died (``RecordingContents.end`` is None).

fsync policy: the writer thread wakes every ``flush_interval_s`` (default 0.25 s), concatenates what arrived per
stream into one chunk each, writes them and calls ``os.fsync``. A crash therefore loses at most the last
~0.25 s that was still in memory, never anything already acknowledged as written, and never corrupts earlier data.

Disk faults (ENOSPC, EDQUOT, EFBIG, EIO): the chunk being written is cut back to the last chunk boundary, the
take is closed with an end chunk naming the fault (when even that does not fit, the take reads as "no end
record"), everything written before stays readable, and ``on_event("alarm", ...)`` tells the gateway, which
keeps streaming. Recording can start again (a new take) once space is free.

Memory policy: samples are never dropped while the disk keeps up; `Recorder.put_*` appends to an in-memory
backlog that only the writer thread drains (the display path in `gateway.server` is separate and may drop).
The backlog is bounded by ``max_backlog_bytes`` (default 64 MiB, about 45 s of 4 stations x 6 sensors x 1 kHz):
while it is full, new rows are refused and counted (``samples_dropped``), with one alarm event when refusing
starts and one when it stops at half the bound, so the gap is visible in the take itself.
"""
from __future__ import annotations

import csv
import errno
import json
import logging
import os
import struct
import threading
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO, Callable

import numpy as np

from engine import export_format
from engine import progress
from engine.errors import CourtsideError
from gateway import codec
from gateway.clock import realign_offline
from gateway.names import BadNameError, check_name

log = logging.getLogger(__name__)

FILE_MAGIC = b"CSREC\x00\x01\n"
CHUNK_MAGIC = b"CHNK"
_U32 = struct.Struct(">I")
_CHUNK_HEAD = struct.Struct(">4sII")
RECORDING_FILE = "take.csrec"
META_KIND = "take_meta"  # first chunk: copy of the file header's meta
END_KIND = "take_end"  # last chunk of a take closed on purpose: {"reason", "samples_written", ...}
DEFAULT_MAX_BACKLOG_BYTES = 64 << 20
MAX_META_BYTES = 16 << 20


class RecordingError(CourtsideError, ValueError):
    """A recording file that cannot be read at all (names the file and the problem)."""

    def __init__(self, path: Path | str, problem: str):
        super().__init__(f"{path}: {problem}")
        self.path = Path(path)
        self.problem = problem


class RecorderRefused(CourtsideError, ValueError):
    """A start/stop request the recorder cannot honour (bad or duplicate take name, not recording, no space)."""


def open_exclusive(path: Path) -> BinaryIO:
    """Default file layer: a new file (never overwrite an earlier take), unbuffered so every ``write`` says how
    many bytes reached the kernel and a failed chunk can be cut back exactly."""
    return open(path, "xb", buffering=0)


# ---------------------------------------------------------------------------------------------------- writing
class ChunkFile:
    """Append-only chunk file writer (single writer thread). Every append either lands whole or is cut back."""

    def __init__(self, path: Path, meta: dict[str, Any], opener: Callable[[Path], BinaryIO] = open_exclusive):
        self.path = Path(path)
        self._fh = opener(self.path)
        self.bytes_written = 0
        self.chunks_written = 0
        try:
            meta_bytes = json.dumps(meta, separators=(",", ":")).encode("utf-8")
            self._write_all(FILE_MAGIC + _U32.pack(len(meta_bytes)) + meta_bytes + _U32.pack(zlib.crc32(meta_bytes)))
            self.bytes_written = self._fh.tell()
            self.append(codec.encode(META_KIND, {"meta": meta}))
            self.sync()
        except OSError:
            self._fh.close()
            self.path.unlink(missing_ok=True)  # nothing half-written: a take without its header is no take
            raise

    def _write_all(self, data: bytes) -> None:
        view = memoryview(data)
        done = 0
        while done < len(view):
            n = self._fh.write(view[done:])
            if not n:
                raise OSError(errno.EIO, "write made no progress")
            done += n

    def append(self, body: bytes) -> None:
        """Write one chunk; on an OSError the partial chunk is cut off again before the error propagates."""
        try:
            self._write_all(_CHUNK_HEAD.pack(CHUNK_MAGIC, len(body), zlib.crc32(body)) + body)
        except OSError:
            self._cut_back()
            raise
        self.bytes_written += _CHUNK_HEAD.size + len(body)
        self.chunks_written += 1

    def _cut_back(self) -> None:
        try:
            self._fh.truncate(self.bytes_written)
            self._fh.seek(self.bytes_written)
        except OSError as exc:  # the reader still resynchronises past a torn chunk
            log.warning("%s: cannot cut back a partial chunk: %s", self.path, exc)

    def sync(self) -> None:
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def close(self, end: dict[str, Any] | None = None) -> bool:
        """Write the end chunk (if given), fsync and close. Never raises: returns False when the end chunk or the
        final fsync did not make it (the take then reads as one without an end record)."""
        if self._fh.closed:
            return False
        ok = True
        try:
            if end is not None:
                self.append(codec.encode(END_KIND, end))
            self.sync()
        except OSError as exc:
            log.warning("%s: end of take not written: %s", self.path, exc)
            ok = False
        try:
            self._fh.close()
        except OSError:
            ok = False
        return ok


def _remove_leftovers(take_dir: Path, made_dir: bool) -> None:
    """After a refused start: the take file (checked absent before, so ours, at most a partial header) and the
    take directory if this start made it; a refused take leaves nothing behind (issue 22)."""
    try:
        (take_dir / RECORDING_FILE).unlink(missing_ok=True)
        if made_dir:
            take_dir.rmdir()
    except OSError as exc:
        log.warning("%s: cannot remove what a refused start left: %s", take_dir, exc.strerror or exc)


def _same_array_runs(batches: list[dict[str, np.ndarray]]) -> list[list[dict[str, np.ndarray]]]:
    """Consecutive batches carrying the same arrays, in order (each run becomes one chunk)."""
    runs: list[list[dict[str, np.ndarray]]] = []
    for batch in batches:
        if runs and list(runs[-1][0]) == list(batch):
            runs[-1].append(batch)
        else:
            runs.append([batch])
    return runs


def describe_os_error(exc: BaseException) -> str:
    """``"disk full (ENOSPC)"``-style text for an OSError, the exception text otherwise."""
    if isinstance(exc, OSError) and exc.errno is not None:
        name = errno.errorcode.get(exc.errno, str(exc.errno))
        return f"{exc.strerror or os.strerror(exc.errno)} ({name})"
    return f"{type(exc).__name__}: {exc}"


@dataclass
class _Pending:
    """What arrived since the last flush."""

    # (kind, station, sensor) -> row batches of a tabular stream ("samples", "clock_points")
    rows: dict[tuple[str, str, int], list[dict[str, np.ndarray]]] = field(default_factory=dict)
    headers: dict[tuple[str, str, int], dict[str, Any]] = field(default_factory=dict)
    others: list[bytes] = field(default_factory=list)
    n_samples: int = 0
    n_bytes: int = 0


class Recorder:
    """Records one take at a time. Thread-safe `put_*`; a writer thread does all disk I/O.

    ``opener`` is the file layer (tests and the soak bench pass a fault-injecting one); ``on_event(level,
    message)`` is called (never under the recorder's lock) for disk faults and backlog refusals."""

    def __init__(self, record_dir: Path | str, flush_interval_s: float = 0.25, *,
                 max_backlog_bytes: int = DEFAULT_MAX_BACKLOG_BYTES,
                 opener: Callable[[Path], BinaryIO] = open_exclusive,
                 on_event: Callable[[str, str], None] | None = None):
        self.record_dir = Path(record_dir)
        self.flush_interval_s = flush_interval_s
        self.max_backlog_bytes = int(max_backlog_bytes)
        self.opener = opener
        self.on_event = on_event
        self._lock = threading.Lock()
        self._pending = _Pending()
        self._file: ChunkFile | None = None
        self._take: str | None = None
        self._started_s = 0.0
        self._samples_written = 0
        self._samples_queued = 0
        self._samples_dropped = 0
        self._backlog_bytes = 0
        self._refusing = False
        self._fault: str | None = None
        self._events: list[tuple[str, str]] = []  # (level, message) to deliver outside the lock
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last: dict[str, Any] = {"active": False, "take": None, "fault": None}

    @property
    def active(self) -> bool:
        return self._file is not None

    def start(self, take: str, meta: dict[str, Any] | None = None) -> dict[str, Any]:
        """Open ``<record_dir>/<take>/take.csrec`` and start writing. Raises RecorderRefused (a ValueError) on a
        bad/duplicate take name, while recording, or when the file cannot be created (disk full...)."""
        try:
            check_name(take, "take name")  # one definition of a safe take name (issue 12: "..", ".", newlines)
        except BadNameError as exc:
            raise RecorderRefused(str(exc)) from None
        with self._lock:
            if self._file is not None:
                raise RecorderRefused(f"already recording take {self._take!r}")
            take_dir = self.record_dir / take
            if (take_dir / RECORDING_FILE).exists():
                raise RecorderRefused(f"take {take!r} already exists in {self.record_dir}")
            started_s = time.monotonic()
            full_meta = {"take": take, "started_t_host_s": started_s,
                         "started_unix_s": time.time(), "format": "courtside-csrec-1", **(meta or {})}
            made_dir = not take_dir.exists()
            try:
                take_dir.mkdir(parents=True, exist_ok=True)
                self._file = ChunkFile(take_dir / RECORDING_FILE, full_meta, self.opener)
            except OSError as exc:
                _remove_leftovers(take_dir, made_dir)
                raise RecorderRefused(f"cannot start take {take!r} in {self.record_dir}: "
                                      f"{describe_os_error(exc)}") from exc
            self._started_s = started_s
            self._take = take
            self._pending = _Pending()
            self._samples_written = self._samples_queued = self._samples_dropped = self._backlog_bytes = 0
            self._refusing = False
            self._fault = None
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
        n_bytes = sum(a.nbytes for a in arrays.values())
        n = len(next(iter(arrays.values()))) if kind == "samples" else 0
        with self._lock:
            if self._file is None:
                return
            if self._admit(n_bytes):
                key = (kind, station, int(sensor))
                self._pending.rows.setdefault(key, []).append(arrays)
                if header:
                    self._pending.headers[key] = header
                self._pending.n_samples += n
                self._pending.n_bytes += n_bytes
                self._samples_queued += n
            else:
                self._samples_dropped += n
        self._announce()

    def put(self, kind: str, header: dict[str, Any], arrays: dict[str, np.ndarray] | None = None) -> None:
        """Queue any other message (camera, event, clock, station hello...) verbatim."""
        body = codec.encode(kind, {"t_host_s": time.monotonic(), **header}, arrays)
        with self._lock:
            if self._file is not None and self._admit(len(body)):
                self._pending.others.append(body)
                self._pending.n_bytes += len(body)
        self._announce()

    def _admit(self, n_bytes: int) -> bool:
        """Backlog policy (caller holds the lock): refuse while the bound is exceeded, resume below half of it."""
        if self._refusing and self._backlog_bytes < self.max_backlog_bytes // 2:
            self._refusing = False
            self._events.append(("warning", f"recording take {self._take} resumed after refusing "
                                            f"{self._samples_dropped} samples (disk too slow)"))
        if not self._refusing and self._backlog_bytes + n_bytes > self.max_backlog_bytes:
            self._refusing = True
            self._events.append(("alarm", f"recording take {self._take}: disk too slow, backlog reached "
                                          f"{self._backlog_bytes} bytes; refusing new samples until it halves"))
        if self._refusing:
            return False
        self._backlog_bytes += n_bytes
        return True

    def _announce(self) -> None:
        """Deliver queued events outside the lock (the gateway's handler records events through `put`)."""
        if not self._events:
            return
        with self._lock:
            events, self._events = self._events, []
        for level, message in events:
            log.warning("%s", message)
            if self.on_event is not None:
                self.on_event(level, message)

    def _write_loop(self) -> None:
        while not self._stop.wait(self.flush_interval_s):
            self._flush()
        self._flush()
        self._announce()

    def _flush(self) -> None:
        with self._lock:
            pending, self._pending = self._pending, _Pending()
            chunk_file = self._file
        if chunk_file is None:
            return
        written_samples = 0
        try:
            bodies = [(body, 0) for body in pending.others]
            for (kind, station, sensor), batches in pending.rows.items():
                header = {**pending.headers.get((kind, station, sensor), {}), "station": station, "sensor": sensor}
                for run in _same_array_runs(batches):  # a sensor that starts/stops streaming orientation
                    arrays = {name: np.concatenate([b[name] for b in run]) for name in run[0]}
                    n = len(next(iter(arrays.values()))) if kind == "samples" else 0
                    bodies.append((codec.encode(kind, header, arrays), n))
            for body, n in bodies:
                chunk_file.append(body)
                written_samples += n
            if bodies:
                chunk_file.sync()
        except Exception as exc:  # a disk fault (or a bug) ends the take cleanly instead of killing this thread
            if not isinstance(exc, OSError):
                log.exception("recorder: writing failed")
            self._fail(chunk_file, exc, written_samples)
            return
        with self._lock:
            self._samples_written += pending.n_samples
            self._backlog_bytes -= pending.n_bytes

    def _fail(self, chunk_file: ChunkFile, exc: BaseException, written_samples: int) -> None:
        """Close the take after a write fault: keep what is on disk, free the backlog, tell the gateway."""
        fault = describe_os_error(exc)
        with self._lock:
            if self._file is not chunk_file:
                return
            self._samples_written += written_samples
            lost = self._samples_queued - self._samples_written
            self._fault = fault
            state = self.state_locked()
            # the backlog was freed (its samples are counted as lost): the figures say so (issue 22)
            state.update(active=False, files=[str(chunk_file.path)], samples_lost=lost, samples_backlog=0,
                         backlog_bytes=0)
            self._last = state
            self._file = None
            self._pending = _Pending()
            self._backlog_bytes = 0
        self._stop.set()
        state["end_written"] = chunk_file.close(end={
            "reason": "fault", "fault": fault, "samples_written": state["samples_written"], "samples_lost": lost,
            "t_host_s": time.monotonic()})
        with self._lock:
            self._events.append(("alarm", f"recording take {state['take']} stopped: {fault}; kept "
                                          f"{state['samples_written']} samples in {chunk_file.path}, "
                                          f"{lost} queued samples not written"))
        self._announce()

    def stop(self) -> dict[str, Any]:
        """Flush everything queued, write the end chunk, fsync, close. Returns the final state (with ``files``)."""
        with self._lock:
            thread, chunk_file = self._thread, self._file
            if chunk_file is None:
                fault = self._last.get("fault")
                raise RecorderRefused("not recording" + (f" (take {self._last.get('take')!r} was stopped by a "
                                                         f"disk fault: {fault})" if fault else ""))
        self._stop.set()
        if thread is not None:
            thread.join()
        with self._lock:
            if self._file is not chunk_file:  # the final flush hit a fault: _fail closed the take
                return dict(self._last)
            state = self.state_locked()
            self._file = None
        chunk_file.close(end={"reason": "stopped", "samples_written": state["samples_written"],
                              "samples_dropped": state["samples_dropped"], "t_host_s": time.monotonic()})
        state.update(active=False, files=[str(chunk_file.path)], bytes_written=chunk_file.bytes_written,
                     chunks_written=chunk_file.chunks_written)
        with self._lock:
            self._last = state
        log.info("recording %s stopped: %d samples", state["take"], state["samples_written"])
        return state

    def state_locked(self) -> dict[str, Any]:
        f = self._file
        if f is None:
            return dict(self._last)
        return {"active": True, "take": self._take, "path": str(f.path), "started_t_host_s": self._started_s,
                "samples_written": self._samples_written, "samples_backlog": self._samples_queued - self._samples_written,
                "backlog_bytes": self._backlog_bytes, "samples_dropped": self._samples_dropped, "fault": self._fault,
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
    messages: list[codec.Message]  # every intact chunk except the take_meta / take_end records
    intact_bytes: int  # bytes up to the end of the last intact chunk
    total_bytes: int
    problem: str | None  # what was damaged or cut (None if the file is whole)
    end: dict[str, Any] | None = None  # the take_end record: None = the writer never closed the take (crash)
    skipped: list[tuple[int, int, str]] = field(default_factory=list)  # damaged regions: (byte, length, why)
    header_recovered: bool = False  # the file header was damaged; meta comes from its copy in the first chunk

    @property
    def truncated(self) -> bool:
        return self.problem is not None

    @property
    def ended_cleanly(self) -> bool:
        """True only for a take stopped on purpose (not crashed, not ended by a disk fault)."""
        return self.end is not None and self.end.get("reason") == "stopped"


def _chunk_at(data: bytes, pos: int) -> tuple[int, int] | str:
    """(body start, body end) of an intact chunk at ``pos``, or why there is none."""
    if pos + _CHUNK_HEAD.size > len(data):
        return "truncated chunk header"
    magic, body_len, crc = _CHUNK_HEAD.unpack_from(data, pos)
    if magic != CHUNK_MAGIC:
        return "bad chunk magic"
    start = pos + _CHUNK_HEAD.size
    if start + body_len > len(data):
        return f"truncated chunk body ({len(data) - start} of {body_len} bytes)"
    if zlib.crc32(memoryview(data)[start:start + body_len]) != crc:
        return "chunk CRC mismatch"
    return start, start + body_len


def _resync(data: bytes, pos: int) -> int | None:
    """Offset of the next intact chunk at or after ``pos`` (its magic, length and CRC agree), else None."""
    while (pos := data.find(CHUNK_MAGIC, pos)) >= 0:
        if isinstance(_chunk_at(data, pos), tuple):
            return pos
        pos += 1
    return None


def _read_header(data: bytes) -> tuple[dict[str, Any], int] | str:
    """(meta, offset of the first chunk) from the file header, or why it is unusable."""
    if len(data) < len(FILE_MAGIC) + 4 or not data.startswith(FILE_MAGIC):
        return "bad or missing file magic"
    (meta_len,) = _U32.unpack_from(data, len(FILE_MAGIC))
    meta_start = len(FILE_MAGIC) + 4
    meta_end = meta_start + meta_len
    if meta_len > MAX_META_BYTES or meta_end + 4 > len(data):
        return "file header is truncated or its length is damaged"
    meta_bytes = data[meta_start:meta_end]
    if zlib.crc32(meta_bytes) != _U32.unpack_from(data, meta_end)[0]:
        return "file header CRC mismatch"
    try:
        meta = json.loads(meta_bytes.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        return f"file header is not UTF-8 JSON ({exc})"
    if not isinstance(meta, dict):
        return "file header is not a JSON object"
    return meta, meta_end + 4


def read_recording(path: Path | str) -> RecordingContents:
    """Read a recording. A torn tail (crash mid-write) and damaged chunks are skipped and reported in
    ``problem`` / ``skipped``; a damaged file header is replaced by its copy. RecordingError when nothing usable
    is left, or when an intact chunk (valid CRC) does not decode (a foreign or buggy writer, not damage)."""
    path = Path(path)
    if path.is_dir():
        path = path / RECORDING_FILE
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise RecordingError(path, f"cannot read: {exc.strerror or exc}") from exc
    header = _read_header(data)
    if isinstance(header, str):
        header_problem, meta, pos = header, None, _resync(data, 0)
        if pos is None:
            if header.startswith("bad or missing file magic"):
                raise RecordingError(path, "not a Courtside recording (bad or missing file magic)")
            raise RecordingError(path, f"{header_problem} (crashed before the first fsync?)")
    else:
        header_problem, (meta, pos) = None, header
    messages: list[codec.Message] = []
    skipped: list[tuple[int, int, str]] = []
    tail: str | None = None
    end: dict[str, Any] | None = None
    intact = pos
    meter = progress.bar(total=len(data), desc=f"reading {path.parent.name}", unit="B")
    while pos < len(data):
        meter.update(pos - meter.n)
        where = _chunk_at(data, pos)
        if isinstance(where, str):
            nxt = _resync(data, pos + 1)
            if nxt is None:
                tail = f"{where} at byte {pos}"
                break
            skipped.append((pos, nxt - pos, where))
            pos = nxt
            continue
        start, stop = where
        try:
            msg = codec.decode(memoryview(data)[start:stop])
        except codec.CodecError as exc:
            raise RecordingError(path, f"intact chunk at byte {pos} does not decode: {exc}") from exc
        if msg.kind == META_KIND:
            if meta is None and isinstance(msg.header.get("meta"), dict):
                meta = msg.header["meta"]
        elif msg.kind == END_KIND:
            end = msg.header
        else:
            messages.append(msg)
        pos = intact = stop
    meter.close()
    if meta is None:
        raise RecordingError(path, f"{header_problem} and no intact copy of it in the first chunk")
    problems = [f"{header_problem}; meta recovered from its copy"] if header_problem else []
    if skipped:
        problems.append(f"skipped {len(skipped)} damaged region(s), {sum(n for _, n, _ in skipped)} bytes "
                        f"(first at byte {skipped[0][0]}: {skipped[0][2]})")
    if tail:
        problems.append(tail)
    problem = "; ".join(problems) or None
    if problem:
        log.warning("%s: %s; keeping %d intact chunks", path, problem, len(messages))
    return RecordingContents(path, meta, messages, intact, len(data), problem, end, skipped, header_problem is not None)


@dataclass
class Take:
    """A recording reassembled per stream, arrays concatenated in time order:
    ``samples[(station, sensor)][name]``, ``clock_points[station][name]`` (every clock-sync point: ``raw_ticks``,
    ``ticks``, ``epoch``, ``arrival_s``; ``tick_hz`` in ``clock_tick_hz[station]``), other messages in ``others``.
    ``end`` is the take_end record (None: the writer never closed the take, e.g. a crash). ``sample_athletes``: who
    wore each sample stream (its chunks' ``athlete`` tag; streams nobody wore, or recorded before athletes, absent)."""

    meta: dict[str, Any]
    samples: dict[tuple[str, int], dict[str, np.ndarray]]
    clock_points: dict[str, dict[str, np.ndarray]]
    clock_tick_hz: dict[str, float]
    others: list[codec.Message]
    problem: str | None
    end: dict[str, Any] | None = None
    sample_athletes: dict[tuple[str, int], str] = field(default_factory=dict)


_CLOCK_POINT_ARRAYS = ("raw_ticks", "ticks", "epoch", "arrival_s")


def _stream_key(path: Path, msg: codec.Message, required: tuple[str, ...]) -> tuple[str, int]:
    """(station, sensor) of a tabular chunk, checking what `load_take` relies on (a CRC-valid chunk from a
    foreign or buggy writer must give a clear error, not a KeyError)."""
    station, sensor = msg.header.get("station"), msg.header.get("sensor")
    if not isinstance(station, str) or isinstance(sensor, bool) or not isinstance(sensor, int):
        raise RecordingError(path, f"{msg.kind} chunk without a string 'station' and an integer 'sensor' "
                                   f"(header {sorted(msg.header)})")
    missing = [name for name in required if name not in msg.arrays]
    lengths = {a.shape[0] if a.ndim else -1 for a in msg.arrays.values()}
    if missing or len(lengths) > 1 or -1 in lengths:
        raise RecordingError(path, f"{msg.kind} chunk of {station}/{sensor}: missing arrays {missing} or arrays of "
                                   "different lengths")
    return station, sensor


OPTIONAL_CHANNELS = {"quat_wxyz": 4, "gyro_rps": 3}
"""Per-sample arrays a sensor may stream in some chunks only (e.g. an IMU whose filter was switched on): rows of
chunks without them read NaN."""


def _concatenate(path: Path, what: str, msgs: list[codec.Message]) -> dict[str, np.ndarray]:
    names = list(msgs[0].arrays)
    for m in msgs:
        names += [name for name in m.arrays if name not in names]
    if any([n for n in names if n in m.arrays or n not in OPTIONAL_CHANNELS] != list(m.arrays) for m in msgs):
        raise RecordingError(path, f"{what}: chunks carry different arrays")

    def rows(m: codec.Message, name: str) -> np.ndarray:
        if name in m.arrays:
            return m.arrays[name]
        return np.full((len(next(iter(m.arrays.values()))), OPTIONAL_CHANNELS[name]), np.nan, np.float32)

    try:
        return {name: np.concatenate([rows(m, name) for m in msgs]) for name in names}
    except ValueError as exc:
        raise RecordingError(path, f"{what}: chunks do not concatenate ({exc})") from exc


def load_take(path: Path | str) -> Take:
    contents = read_recording(path)
    path = contents.path
    samples: dict[tuple[str, int], list[codec.Message]] = {}
    points: dict[str, list[codec.Message]] = {}
    others = []
    for msg in contents.messages:
        if msg.kind == "samples":
            samples.setdefault(_stream_key(path, msg, ()), []).append(msg)
        elif msg.kind == "clock_points":
            station, _ = _stream_key(path, msg, _CLOCK_POINT_ARRAYS)
            tick_hz = msg.header.get("tick_hz")
            if isinstance(tick_hz, bool) or not isinstance(tick_hz, (int, float)) or not tick_hz > 0:
                raise RecordingError(path, f"clock_points chunk of {station} without a positive 'tick_hz'")
            points.setdefault(station, []).append(msg)
        else:
            others.append(msg)
    return Take(
        contents.meta,
        {key: _concatenate(path, f"samples of {key[0]}/{key[1]}", msgs) for key, msgs in sorted(samples.items())},
        {station: _concatenate(path, f"clock points of {station}", msgs) for station, msgs in sorted(points.items())},
        {station: float(msgs[-1].header["tick_hz"]) for station, msgs in points.items()},
        others, contents.problem, contents.end,
        {key: str(msgs[0].header["athlete"]) for key, msgs in sorted(samples.items()) if "athlete" in msgs[0].header},
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


def _exportable(path: Path | str) -> Take:
    """The take, checked for what the exporters rely on: every sample stream has its times."""
    take = load_take(path)
    path = Path(path) / RECORDING_FILE if Path(path).is_dir() else path
    for (station, sensor), cols in take.samples.items():
        if "t_host_s" not in cols:
            raise RecordingError(path, f"samples of {station}/{sensor} carry no 't_host_s' (not a gateway recording?)")
    if take.end is None:
        log.warning("%s: no end record: the take was never closed (crash or power loss); exporting everything up "
                    "to its last intact chunk", path)
    elif take.end.get("reason") == "fault":
        log.warning("%s: the take was ended by a disk fault (%s)", path, take.end.get("fault"))
    return take


def export_take(path: Path | str, npz: Path | str | None = None, csv_dir: Path | str | None = None) -> list[Path]:
    """`export_npz` and/or `export_csv` from one reading of the take, so its warnings (never closed, ended by a
    disk fault) are printed once (issue 22: twice with --npz and --csv-dir). Returns the files written."""
    if npz is not None:
        _check_output_dir(Path(npz).parent)  # before any work or warning
    take = _exportable(path)
    written = [export_npz(path, npz, take=take)] if npz is not None else []
    return written + (export_csv(path, csv_dir, take=take) if csv_dir is not None else [])


def export_npz(path: Path | str, out: Path | str, *, take: Take | None = None) -> Path:
    """One npz in the layout `engine.export_format` defines: ``<station>/<sensor>/<array>`` keys for samples
    (plus ``t_realigned_s``, the offline clock re-fit), ``meta`` and ``messages`` as JSON strings. ``take``: the
    take at ``path`` when already loaded."""
    out = Path(out)
    _check_output_dir(out.parent)  # before any work or warning
    take = take or _exportable(path)
    realigned = realign_take(take)
    arrays: dict[str, Any] = {}
    for (station, sensor), cols in take.samples.items():
        for name, value in {**cols, export_format.T_REALIGNED_S: realigned[(station, sensor)]}.items():
            arrays[export_format.sensor_key(export_format.sensor_name(station, sensor), name)] = value
    arrays[export_format.META] = np.array(json.dumps(take.meta))
    arrays[export_format.MESSAGES] = np.array(json.dumps([{"kind": m.kind, **m.header} for m in take.others]))
    partial = out.with_name(out.name + ".partial")
    try:
        with open(partial, "wb") as fh:  # a file object: numpy does not append ".npz" to the name
            np.savez_compressed(fh, **arrays)
        os.replace(partial, out)  # nothing half-written under the final name
    except OSError as exc:
        partial.unlink(missing_ok=True)
        raise CourtsideError(f"{out}: cannot write: {describe_os_error(exc)}") from exc
    return out


def _check_output_dir(directory: Path) -> None:
    if not directory.is_dir():
        raise CourtsideError(f"{directory}: output directory does not exist")


def export_csv(path: Path | str, out_dir: Path | str, *, take: Take | None = None) -> list[Path]:
    """One CSV per sensor (``<station>_<sensor>.csv``: one row per sample, vector arrays split into columns, plus
    ``t_realigned_s``) and ``messages.csv`` (t_host_s, kind, JSON header) for everything else."""
    take = take or _exportable(path)
    realigned = realign_take(take)
    out_dir = Path(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CourtsideError(f"{out_dir}: cannot create the output directory: {describe_os_error(exc)}") from exc
    written = []
    for (station, sensor), cols in take.samples.items():
        names, columns = [], []
        for name, value in {**cols, export_format.T_REALIGNED_S: realigned[(station, sensor)]}.items():
            value = value.reshape(len(value), -1)
            if value.shape[1] == 1:
                names.append(name)
            else:
                suffixes = {3: "xyz", 4: "wxyz"}.get(value.shape[1], [str(i) for i in range(value.shape[1])])
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
