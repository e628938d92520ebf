"""Image queues and the worker threads that empty them (plain Python).

They move tag detection off the caller's thread (the ROS node's subscription callbacks, the
``bag`` replay's reader). :class:`ImageQueue` is one bounded drop-oldest FIFO.
:class:`FairImageQueue` keeps one bounded FIFO per camera and serves the cameras round-robin, so
that a fast camera cannot starve the others, and hands out at most one image per camera at a
time, oldest first: the motion gate of the session needs the pairs of a camera's previous image
before it decides about the next (:mod:`rwhec_ros.session.image_input`). Its ``ready`` predicate
holds an image back until the session has the pose at its stamp, so that images wait in the queue
(undecoded), not in the session. Live, a full camera queue drops its oldest image (fresh images
matter most) and counts it; offline (``block=True``) ``put`` waits for room instead.
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable, Hashable, Sequence
from typing import Any

__all__ = ["ImageQueue", "FairImageQueue", "QueueWorker"]


class _Closable:
    """Closing, shared by the queues: wake every waiter; ``get`` then hands out what is left and
    returns None, a blocked ``put`` gives up. Needs ``_cond`` and ``_closed``."""

    _cond: threading.Condition
    _closed: bool

    def close(self) -> None:
        """Close the queue (see the class docstring)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    @property
    def closed(self) -> bool:
        with self._cond:
            return self._closed


class ImageQueue(_Closable):
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

    @property
    def dropped(self) -> int:
        with self._cond:
            return self._dropped

    def __len__(self) -> int:
        with self._cond:
            return len(self._items)


class FairImageQueue(_Closable):
    """One bounded FIFO per key (camera), served round-robin; one item per key in service.

    Thread-safe. :meth:`get` returns ``(key, item)`` of the next key in round-robin order whose
    oldest item is ready and that has no item in service; the consumer calls
    :meth:`task_done` with that pair when it is finished with it (:class:`QueueWorker` does).

    Parameters
    ----------
    keys : sequence of hashable
        The keys (camera names); :meth:`put` with another key raises ``KeyError``.
    maxsize : int
        Items held per key (>= 1).
    ready : callable(item) -> bool, optional
        Whether the oldest item of a key may be handed out now (e.g. the session has the pose at
        its stamp). It is called with the queue's lock held, so it must not call back into the
        queue. Call :meth:`notify` when readiness may have changed (a new pose); consumers also
        re-check every ``recheck_s`` seconds.
    block : bool
        ``put`` on a full key waits for room (offline: nothing is lost) instead of dropping the
        key's oldest item (live).
    expendable : callable(key, item) -> bool, optional
        Live, on a full key: the oldest item for which it returns True is dropped instead of the
        key's oldest item (e.g. an image the motion gate would skip anyway). Called by
        :meth:`put` WITHOUT the queue's lock (it may be slow or take other locks); it must not
        call back into the queue.
    recheck_s : float
        Longest wait of :meth:`get` before it looks at readiness again.
    """

    def __init__(
        self,
        keys: Sequence[Hashable],
        maxsize: int,
        *,
        ready: Callable[[Any], bool] | None = None,
        block: bool = False,
        recheck_s: float = 0.05,
        expendable: Callable[[Hashable, Any], bool] | None = None,
    ) -> None:
        if isinstance(maxsize, bool) or not isinstance(maxsize, int) or maxsize < 1:
            raise ValueError(f"maxsize: expected an integer >= 1, got {maxsize!r}")
        self.keys = tuple(keys)
        if not self.keys or len(set(self.keys)) != len(self.keys):
            raise ValueError(f"keys: expected distinct keys, at least one, got {list(keys)!r}")
        if not recheck_s > 0:
            raise ValueError(f"recheck_s: must be > 0, got {recheck_s!r}")
        self.maxsize = maxsize
        self.block = bool(block)
        self._ready = ready
        self._expendable = expendable
        self._recheck_s = float(recheck_s)
        self._queues = {k: collections.deque() for k in self.keys}
        self._busy: set = set()
        self._next = 0
        self._cond = threading.Condition()
        self._closed = False
        self._stats = {k: dict.fromkeys(("received", "dropped", "dropped_expendable",
                                         "processed"), 0)
                       for k in self.keys}

    def put(self, key: Hashable, item: Any) -> bool:
        """Enqueue ``item`` for ``key``; returns False when the key's oldest item had to be
        dropped (counted). With ``block`` it waits for room instead (returns False only when
        the queue was closed meanwhile, the item not enqueued).

        Live, on a full key with an ``expendable`` predicate, the key's items are judged
        outside the queue's lock (the predicate may take the session's lock and does real
        work), so that the consumers are never held up by a drop decision."""
        q = self._queues[key]
        with self._cond:
            self._stats[key]["received"] += 1
            if self.block:
                while len(q) >= self.maxsize and not self._closed:
                    self._cond.wait()
                if self._closed:
                    return False
            elif len(q) >= self.maxsize and self._expendable is None:
                q.popleft()
                self._stats[key]["dropped"] += 1
                q.append(item)
                self._cond.notify_all()
                return False
            if len(q) < self.maxsize:
                q.append(item)
                self._cond.notify_all()
                return True
            candidates = list(q)
        victim = next((c for c in candidates if self._expendable(key, c)), None)
        with self._cond:
            dropped = len(q) >= self.maxsize  # a consumer may have made room meanwhile
            if dropped:
                self._drop_one(key, q, victim)
            q.append(item)
            self._cond.notify_all()
            return not dropped

    def _drop_one(self, key: Hashable, q: collections.deque, victim: Any) -> None:
        """Drop ``victim`` (an expendable item) from the full ``q`` if it is still queued, else
        the key's oldest item; counted (lock held)."""
        self._stats[key]["dropped"] += 1
        if victim is not None:
            for i, queued in enumerate(q):
                if queued is victim:
                    del q[i]
                    self._stats[key]["dropped_expendable"] += 1
                    return
        q.popleft()

    def _take(self) -> tuple[Hashable, Any] | None:
        """The next servable ``(key, item)`` in round-robin order (lock held), or None."""
        n = len(self.keys)
        for i in range(n):
            key = self.keys[(self._next + i) % n]
            q = self._queues[key]
            if not q or key in self._busy:
                continue
            if self._ready is not None and not self._closed and not self._ready(q[0]):
                continue
            self._next = (self._next + i + 1) % n
            self._busy.add(key)
            item = q.popleft()
            self._cond.notify_all()  # room for a blocked put
            return key, item
        return None

    def get(self, timeout: float | None = None) -> tuple[Hashable, Any] | None:
        """Next ``(key, item)``, or None after ``timeout`` seconds or once closed and empty.

        After :meth:`close` the remaining items are handed out without the ``ready`` check."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._cond:
            while True:
                entry = self._take()
                if entry is not None:
                    return entry
                if self._closed and not any(self._queues.values()):
                    return None
                if not self._wait(deadline):
                    return None

    def task_done(self, entry: tuple[Hashable, Any]) -> None:
        """The consumer finished ``entry`` (from :meth:`get`): its key may be served again."""
        key = entry[0]
        with self._cond:
            self._busy.discard(key)
            self._stats[key]["processed"] += 1
            self._cond.notify_all()

    def notify(self) -> None:
        """Readiness may have changed (e.g. a new pose arrived): wake the consumers."""
        with self._cond:
            self._cond.notify_all()

    def join(self, timeout: float | None = None) -> bool:
        """Wait until every queue is empty and nothing is in service; False on timeout."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._cond:
            while any(self._queues.values()) or self._busy:
                if not self._wait(deadline):
                    return False
            return True

    def _wait(self, deadline: float | None) -> bool:
        """Wait (lock held) until notified, at most ``recheck_s`` and not past ``deadline``
        (``time.monotonic``); False when the deadline has passed."""
        wait = self._recheck_s
        if deadline is not None:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            wait = min(wait, remaining)
        self._cond.wait(wait)
        return True

    @property
    def dropped(self) -> int:
        """Items dropped over all keys."""
        with self._cond:
            return sum(s["dropped"] for s in self._stats.values())

    def stats(self) -> dict[Hashable, dict[str, int]]:
        """Per key: ``received`` (put), ``dropped`` (dropped when full), of which
        ``dropped_expendable`` (an expendable item rather than the oldest), ``processed`` (handed
        out and done) and ``queued`` (waiting now)."""
        with self._cond:
            return {k: {**s, "queued": len(self._queues[k])} for k, s in self._stats.items()}

    def __len__(self) -> int:
        with self._cond:
            return sum(len(q) for q in self._queues.values())


class QueueWorker:
    """A daemon thread that feeds every item of an :class:`ImageQueue` or every ``(key, item)``
    of a :class:`FairImageQueue` to ``handler`` (and then calls the queue's ``task_done``).

    Exceptions raised by ``handler`` are counted (``errors``) and passed to ``on_error`` (e.g. a
    throttled logger); they never stop the worker.
    """

    def __init__(
        self,
        queue: ImageQueue | FairImageQueue,
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
                done = getattr(self.queue, "task_done", None)
                if done is not None:
                    done(item)

    def stop(self, timeout: float | None = 2.0) -> None:
        """Stop after the current item and join the thread."""
        self._stop.set()
        self.queue.close()
        if self._thread.is_alive():
            self._thread.join(timeout)

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

