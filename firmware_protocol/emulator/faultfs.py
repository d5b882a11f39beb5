"""A file layer whose disk fills and frees on demand, for the recorder's fault tests and the soak benchmark.

Why not a real small filesystem: mounting one needs root. This layer writes real files through the kernel and
behaves the way a full ext4 does at the system-call level: a write that does not fit stores the bytes that do
and raises ``OSError(ENOSPC)`` on the next attempt (a short write, then the error), and truncating a file gives
its bytes back. `gateway.recorder.Recorder(opener=disk.open)` uses it in place of `open_exclusive`.
"""
from __future__ import annotations

import errno
import io
import os
import threading
from pathlib import Path


class SimulatedDisk:
    """Shared free-space budget (bytes) for every file opened through it."""

    def __init__(self, free_bytes: int):
        self._free = int(free_bytes)
        self._lock = threading.Lock()
        self.enospc_count = 0  # writes refused so far

    @property
    def free_bytes(self) -> int:
        return self._free

    def set_free(self, free_bytes: int) -> None:
        """The operator deleted (or another process wrote) files: this much space is free now."""
        with self._lock:
            self._free = int(free_bytes)

    def _take(self, wanted: int) -> int:
        with self._lock:
            granted = min(wanted, self._free)
            if granted == 0 and wanted > 0:
                self.enospc_count += 1
            self._free -= granted
            return granted

    def _give_back(self, n: int) -> None:
        with self._lock:
            self._free += n

    def open(self, path: Path) -> "FaultFile":
        """Create ``path`` exclusively (like `gateway.recorder.open_exclusive`), unbuffered."""
        return FaultFile(self, path)


class FaultFile(io.FileIO):
    """An unbuffered new file whose writes draw from a `SimulatedDisk`."""

    def __init__(self, disk: SimulatedDisk, path: Path):
        super().__init__(os.fspath(path), "xb")
        self._disk = disk

    def write(self, data) -> int:  # type: ignore[override]
        view = memoryview(data).cast("B")
        granted = self._disk._take(len(view))
        if granted == 0 and len(view) > 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), self.name)
        written = super().write(view[:granted])
        if written is None or written < granted:  # give back what the kernel did not take
            self._disk._give_back(granted - (written or 0))
        return written or 0

    def truncate(self, size: int | None = None) -> int:  # type: ignore[override]
        before = os.fstat(self.fileno()).st_size
        after = super().truncate(size)
        if after < before:
            self._disk._give_back(before - after)
        return after
