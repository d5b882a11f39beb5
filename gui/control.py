"""Run gateway control requests off the GUI thread and deliver the outcome back on it.

`GatewayClient` requests block until the gateway replies; calling them in a slot would freeze the UI on a slow
or dead link. `RequestRunner.call` runs the request on one worker thread (requests stay ordered) and emits
``done(tag, result, error)`` which Qt queues onto the GUI thread."""
from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

from PySide6 import QtCore


class RequestRunner(QtCore.QObject):
    done = QtCore.Signal(str, object, str)  # tag, result (None on error), error message ("" on success)

    def __init__(self, parent: QtCore.QObject | None = None) -> None:
        super().__init__(parent)
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="console-request")

    def call(self, tag: str, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Future:
        def run() -> Any:
            try:
                result = fn(*args, **kwargs)
            except Exception as exc:  # the gateway refused or the link failed: report, never raise into Qt
                self.done.emit(tag, None, f"{type(exc).__name__}: {exc}")
                return None
            self.done.emit(tag, result, "")
            return result
        return self._pool.submit(run)

    def shutdown(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)
