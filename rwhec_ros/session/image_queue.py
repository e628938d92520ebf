"""A bounded drop-oldest image queue and the worker thread that empties it (plain Python).

They move tag detection off the caller's thread (the ROS node's subscription callbacks); fresh
images matter most live, so a full queue drops its oldest item and counts it.
"""

from __future__ import annotations

import collections
import threading
from collections.abc import Callable
from typing import Any

__all__ = ["ImageQueue", "QueueWorker"]


class ImageQueue:
    """Bounded FIFO that drops the OLDEST item when full (fresh images matter most live).

    Thread-safe. ``put`` never blocks; ``get`` blocks up to ``timeout`` seconds and returns None
    on timeout or after :meth:`close`.
    """

    def __init__(self, maxsize: int) -> None:
        if isinstance(maxsize, bool) or not isinstance(maxsize, int) or maxsize < 1:
            raise ValueError(f"maxsize: expected an integer >= 1, got {maxsize!r}")
        self.maxsize = maxsize
        self._items: collections.deque = collections.deque()
        self._cond = threading.Condition()
        self._dropped = 0
        self._closed = False

    def put(self, item: Any) -> bool:
        """Enqueue ``item``; returns False when an older item had to be dropped (counted)."""
        with self._cond:
            dropped = False
            if len(self._items) >= self.maxsize:
                self._items.popleft()
                self._dropped += 1
                dropped = True
            self._items.append(item)
            self._cond.notify()
            return not dropped

    def get(self, timeout: float | None = None) -> Any | None:
        """Next item, or None after ``timeout`` seconds or once closed and empty."""
        with self._cond:
            if not self._items and not self._closed:
                self._cond.wait(timeout)
            if self._items:
                return self._items.popleft()
            return None

    def close(self) -> None:
        """Wake every waiting ``get``; later ``get`` calls return the remaining items then None."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    @property
    def closed(self) -> bool:
        with self._cond:
            return self._closed

    @property
    def dropped(self) -> int:
        with self._cond:
            return self._dropped

    def __len__(self) -> int:
        with self._cond:
            return len(self._items)


class QueueWorker:
    """A daemon thread that feeds every item of an :class:`ImageQueue` to ``handler``.

    Exceptions raised by ``handler`` are counted (``errors``) and passed to ``on_error`` (e.g. a
    throttled logger); they never stop the worker.
    """

    def __init__(
        self,
        queue: ImageQueue,
        handler: Callable[[Any], Any],
        *,
        name: str = "rwhec-image-worker",
        on_error: Callable[[BaseException], None] | None = None,
    ) -> None:
        self.queue = queue
        self.handler = handler
        self.on_error = on_error
        self.processed = 0
        self.errors = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> QueueWorker:
        self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.is_set():
            item = self.queue.get(timeout=0.1)
            if item is None:
                if self.queue.closed:
                    break
                continue
            try:
                self.handler(item)
            except Exception as exc:  # noqa: BLE001 - the worker must survive bad data
                self.errors += 1
                if self.on_error is not None:
                    try:
                        self.on_error(exc)
                    except Exception:  # noqa: BLE001
                        pass
            finally:
                self.processed += 1

    def stop(self, timeout: float | None = 2.0) -> None:
        """Stop after the current item and join the thread."""
        self._stop.set()
        self.queue.close()
        if self._thread.is_alive():
            self._thread.join(timeout)

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

