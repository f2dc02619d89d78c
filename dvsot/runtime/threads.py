"""Work handed to background threads: calls run in order on one writer thread, and an ordered read-ahead pool.

Both exist so that file writing (HDF5 compression) and frame decoding (OpenCV), which release the GIL,
overlap with event simulation. A failure in a background call is re-raised in the caller's thread at
its next submit, wait or result, never swallowed.
"""

from __future__ import annotations

import queue
import threading
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, TypeVar

T = TypeVar("T")
_STOP = object()


class OrderedWorker:
    """One daemon thread that runs submitted calls in order; at most `depth` calls wait, so memory stays bounded."""

    def __init__(self, name: str, depth: int = 2) -> None:
        self._queue: queue.Queue = queue.Queue(maxsize=depth)
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            try:
                if item is _STOP:
                    return
                if self._error is None:  # after a failure the remaining calls are dropped
                    fn, args = item
                    fn(*args)
            except BaseException as exc:  # handed to the caller's thread by _raise
                self._error = exc
            finally:
                self._queue.task_done()

    def _raise(self) -> None:
        if self._error is not None:
            raise self._error

    def submit(self, fn: Callable[..., Any], *args: Any) -> None:
        """Queue fn(*args) (blocks while `depth` calls wait); raises the error of an earlier call, if any."""
        self._raise()
        if not self._thread.is_alive():
            raise RuntimeError("the background worker has stopped")
        self._queue.put((fn, args))

    def wait(self) -> None:
        """Block until every queued call has run; raises the first error of any of them."""
        self._queue.join()
        self._raise()

    def stop(self) -> None:
        """Drop the calls still waiting, let the running one finish, end the thread (errors are not raised)."""
        if not self._thread.is_alive():
            return
        self._error = self._error or _Stopped()
        self._queue.put(_STOP)
        self._thread.join()


class _Stopped(Exception):
    """Marks a worker stopped on purpose, so that the calls still queued are skipped."""


def read_ahead(load: Callable[[T], Any], items: Iterable[T], workers: int = 2, ahead: int = 4) -> Iterator[Any]:
    """load(item) for each item, in order, computed by `workers` threads up to `ahead` items ahead."""
    pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="read-ahead")
    pending: deque[Future] = deque()
    try:
        for item in items:
            pending.append(pool.submit(load, item))
            if len(pending) > ahead:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()
    finally:
        for fut in pending:
            fut.cancel()
        pool.shutdown(wait=True, cancel_futures=True)
