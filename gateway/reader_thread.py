"""One pyserial-style reader thread (as `serial.threaded.ReaderThread`) under every station reader: the project's
protocol reader (`gateway.station.StationReader`) and the vendor readers (`gateway.vendors.base`).

Why one: both need the same life cycle — open the link, retrying every ``reconnect_interval_s`` until it opens
or the reader stops; serve it (one read, or one batch of library callbacks) until it is lost or stopped; close
it when stopped — and before, each wrote its own thread loop. A subclass sets ``_stop`` (threading.Event),
``_thread`` (None) and ``reconnect_interval_s`` in its constructor and implements the four hooks."""
from __future__ import annotations

import threading


class ReaderThread:
    """start / stop and the reconnecting loop; subclasses implement `_is_open`, `_open`, `_serve`, `_close`."""

    _stop: threading.Event
    _thread: threading.Thread | None
    reconnect_interval_s: float

    @property
    def thread_name(self) -> str:
        return f"gw-{type(self).__name__}"

    def _is_open(self) -> bool:
        """Is the link open now?"""
        raise NotImplementedError

    def _open(self) -> bool:
        """Try to open the link (reporting why not to the sink); False if it cannot be opened now."""
        raise NotImplementedError

    def _serve(self) -> None:
        """One turn on the open link: read and process what came (the loop calls it again at once)."""
        raise NotImplementedError

    def _close(self, reason: str) -> None:
        """Close the link for ``reason`` ("stopped" at `stop`)."""
        raise NotImplementedError

    def start(self) -> "ReaderThread":
        self._thread = threading.Thread(target=self._run, name=self.thread_name, daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 2.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
        self._close("stopped")

    def _run(self) -> None:
        while not self._stop.is_set():
            if not self._is_open() and not self._open():
                self._stop.wait(self.reconnect_interval_s)
                continue
            self._serve()
