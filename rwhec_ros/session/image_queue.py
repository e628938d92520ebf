"""Image queues and the worker threads that empty them (plain Python).

They move tag detection off the caller's thread (the ROS node's subscription callbacks, the
``bag`` replay's reader). :class:`ImageQueue` is one bounded drop-oldest FIFO.
:class:`FairImageQueue` keeps one bounded FIFO per camera and serves the cameras round-robin, so
that a fast camera cannot starve the others, and hands out at most one image per camera at a
time, oldest first: the motion gate of the session needs the pairs of a camera's previous image
before it decides about the next (:mod:`rwhec_ros.session.image_input`). Its ``ready`` predicate
holds an image back until the session has the pose at its stamp (or knows it never will), so that
images wait in the queue (undecoded), not in the session; waiting images are bounded by their
bytes (``max_bytes``), not counted against the camera's backlog. Live, a camera whose backlog is
full drops its oldest image (fresh images matter most) and counts it; offline (``block=True``)
``put`` waits for room instead.
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

    Two kinds of items are held: *ready* ones (the backlog of the consumers) and, with a
    ``ready`` predicate, *waiting* ones (e.g. images whose pose has not arrived yet). ``maxsize``
    bounds a key's backlog: its ready items (a key's items are handed out in order, so they are
    the ones before its first waiting item) that were ready when they were put. Items that had
    to wait are not counted (when a late pose stream catches up, a quarter of a second of images
    of every camera becomes ready at once: that is not the consumers falling behind); they, and
    all items, are bounded by ``max_bytes`` over all keys (with ``weight``): when the items held
    weigh more, the oldest item held is dropped (``"dropped_memory"``, reported to
    ``on_drop``). Without ``ready``, ``maxsize`` bounds every item of a key, as a plain bounded
    queue.

    Parameters
    ----------
    keys : sequence of hashable
        The keys (camera names); :meth:`put` with another key raises ``KeyError``.
    maxsize : int
        Ready items held per key (>= 1).
    ready : callable(item) -> bool, optional
        Whether an item may be handed out now (e.g. the session has the pose at its stamp, or
        knows it never will). It is called with the queue's lock held, so it must not call back
        into the queue. Call :meth:`notify` when readiness may have changed (a new pose);
        consumers also re-check every ``recheck_s`` seconds.
    block : bool
        ``put`` on a full key waits for room (offline: nothing is lost) instead of dropping the
        key's oldest item (live).
    expendable : callable(key, item) -> bool, optional
        Live, on a full key: the oldest ready item for which it returns True is dropped instead
        of the key's oldest item (e.g. an image the motion gate would skip anyway). Called by
        :meth:`put` WITHOUT the queue's lock (it may be slow or take other locks); it must not
        call back into the queue.
    recheck_s : float
        Longest wait of :meth:`get` before it looks at readiness again.
    weight : callable(item) -> int, optional
        Bytes an item holds (default 0: only counts bound the queue).
    max_bytes : int, optional
        Bytes of all the items held beyond which the oldest is dropped (live; default: no bound).
    on_drop : callable(key, item, waiting), optional
        Called (without the lock) for every item dropped for memory, with whether it was still
        waiting (not ready).
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
        weight: Callable[[Any], int] | None = None,
        max_bytes: int | None = None,
        on_drop: Callable[[Hashable, Any, bool], None] | None = None,
    ) -> None:
        if isinstance(maxsize, bool) or not isinstance(maxsize, int) or maxsize < 1:
            raise ValueError(f"maxsize: expected an integer >= 1, got {maxsize!r}")
        self.keys = tuple(keys)
        if not self.keys or len(set(self.keys)) != len(self.keys):
            raise ValueError(f"keys: expected distinct keys, at least one, got {list(keys)!r}")
        if not recheck_s > 0:
            raise ValueError(f"recheck_s: must be > 0, got {recheck_s!r}")
        if max_bytes is not None and not max_bytes > 0:
            raise ValueError(f"max_bytes: must be > 0, got {max_bytes!r}")
        self.maxsize = maxsize
        self.block = bool(block)
        self.max_bytes = max_bytes
        self._ready = ready
        self._expendable = expendable
        self._weight = weight
        self._on_drop = on_drop
        self._recheck_s = float(recheck_s)
        # per key: entries [seq, bytes, item, ready when put] in arrival order
        self._queues = {k: collections.deque() for k in self.keys}
        self._seq = 0
        self._bytes = 0
        self._memory_drops: list = []
        self._busy: set = set()
        self._next = 0
        self._cond = threading.Condition()
        self._closed = False
        self._stats = {k: dict.fromkeys(("received", "dropped", "dropped_expendable",
                                         "dropped_memory", "processed"), 0)
                       for k in self.keys}

    def put(self, key: Hashable, item: Any) -> bool:
        """Enqueue ``item`` for ``key``; returns False when one of the key's ready items had to
        be dropped (counted). With ``block`` it waits for room instead (returns False only when
        the queue was closed meanwhile, the item not enqueued). Items dropped for memory
        (``max_bytes``) are reported to ``on_drop``, not by the return value.

        Live, on a full key with an ``expendable`` predicate, the key's items are judged
        outside the queue's lock (the predicate may take the session's lock and does real
        work), so that the consumers are never held up by a drop decision."""
        try:
            return self._put(key, item)
        finally:
            self._report_drops()

    def _put(self, key: Hashable, item: Any) -> bool:
        """The body of :meth:`put` (memory drops reported after it)."""
        q = self._queues[key]
        size = int(self._weight(item)) if self._weight is not None else 0
        with self._cond:
            self._stats[key]["received"] += 1
            if self.block:
                while len(q) >= self.maxsize and not self._closed:
                    self._cond.wait()
                if self._closed:
                    return False
                return self._append(key, q, item, size)
            counted = self._ready is None or self._ready(item)
            ready, backlog = self._backlog(q)
            if backlog < self.maxsize:
                return self._append(key, q, item, size, counted)
            if self._expendable is None:
                self._drop_one(key, q, None)
                self._append(key, q, item, size, counted)
                return False
            candidates = [e[2] for e in ready]
        victim = next((c for c in candidates if self._expendable(key, c)), None)
        with self._cond:
            dropped = self._backlog(q)[1] >= self.maxsize  # a consumer may have made room
            if dropped:
                self._drop_one(key, q, victim)
            self._append(key, q, item, size, counted)
            return not dropped

    def _backlog(self, q: collections.deque) -> tuple[list, int]:
        """A key's ready entries (before its first waiting one; all without a ``ready``
        predicate) and how many of them count as its backlog, those ready when put (lock
        held)."""
        if self._ready is None:
            return list(q), len(q)
        ready = []
        for entry in q:
            if not self._ready(entry[2]):
                break
            ready.append(entry)
        return ready, sum(1 for e in ready if e[3])

    def _append(self, key: Hashable, q: collections.deque, item: Any, size: int,
                counted: bool = True) -> bool:
        """Append an entry (lock held), then drop the oldest items while the queue holds more
        than ``max_bytes`` (reported to ``on_drop`` after the lock is released); True."""
        self._seq += 1
        q.append([self._seq, size, item, counted])
        self._bytes += size
        self._cond.notify_all()
        if self.max_bytes is None or self._bytes <= self.max_bytes:
            return True
        dropped = []
        while self._bytes > self.max_bytes:
            heads = [(qq[0][0], k) for k, qq in self._queues.items() if qq]
            if not heads:
                break
            k = min(heads)[1]
            entry = self._queues[k].popleft()
            self._bytes -= entry[1]
            self._stats[k]["dropped"] += 1
            self._stats[k]["dropped_memory"] += 1
            waiting = self._ready is not None and not self._ready(entry[2])
            dropped.append((k, entry[2], waiting))
        self._memory_drops += dropped  # reported by put, outside the lock
        return True

    def _report_drops(self) -> None:
        """Tell ``on_drop`` about the items dropped for memory (lock NOT held)."""
        if not self._memory_drops:
            return
        with self._cond:
            dropped, self._memory_drops = self._memory_drops, []
        if self._on_drop is not None:
            for k, it, waiting in dropped:
                self._on_drop(k, it, waiting)

    def _drop_one(self, key: Hashable, q: collections.deque, victim: Any) -> None:
        """Drop ``victim`` (an expendable item) from the full ``q`` if it is still queued, else
        the key's oldest item; counted (lock held)."""
        self._stats[key]["dropped"] += 1
        if victim is not None:
            for i, entry in enumerate(q):
                if entry[2] is victim:
                    del q[i]
                    self._bytes -= entry[1]
                    self._stats[key]["dropped_expendable"] += 1
                    return
        self._bytes -= q.popleft()[1]

    def _take(self) -> tuple[Hashable, Any] | None:
        """The next servable ``(key, item)`` in round-robin order (lock held), or None."""
        n = len(self.keys)
        for i in range(n):
            key = self.keys[(self._next + i) % n]
            q = self._queues[key]
            if not q or key in self._busy:
                continue
            if self._ready is not None and not self._closed and not self._ready(q[0][2]):
                continue
            self._next = (self._next + i + 1) % n
            self._busy.add(key)
            entry = q.popleft()
            self._bytes -= entry[1]
            self._cond.notify_all()  # room for a blocked put
            return key, entry[2]
        return None

    def get(self, timeout: float | None = None) -> tuple[Hashable, Any] | None:
        """Next ``(key, item)``, or None after ``timeout`` seconds or once closed and empty.

        After :meth:`close` the remaining items are handed out without the ``ready`` check
        (unless :meth:`discard` dropped them)."""
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

    def discard(self) -> int:
        """Drop every item held, not counted (shutting down: nothing more is examined); returns
        how many."""
        with self._cond:
            n = sum(len(q) for q in self._queues.values())
            for q in self._queues.values():
                q.clear()
            self._bytes = 0
            self._cond.notify_all()
            return n

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

    @property
    def nbytes(self) -> int:
        """Bytes of the items held (``weight``)."""
        with self._cond:
            return self._bytes

    def stats(self) -> dict[Hashable, dict[str, int]]:
        """Per key: ``received`` (put), ``dropped`` (any drop), of which ``dropped_expendable``
        (an expendable item rather than the oldest, key full) and ``dropped_memory``
        (``max_bytes``), ``processed`` (handed out and done) and ``queued`` (held now)."""
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
        self.request_stop()
        self.queue.close()
        self.join(timeout)

    def request_stop(self) -> None:
        """Take no further item (the current one is finished); returns at once. Several
        workers of one queue: ask them all first, then :meth:`join` them, so that none takes
        the items the others leave."""
        self._stop.set()

    def join(self, timeout: float | None = None) -> bool:
        """Wait up to ``timeout`` s for the thread to end; True when it has."""
        if self._thread.is_alive():
            self._thread.join(timeout)
        return not self._thread.is_alive()

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

