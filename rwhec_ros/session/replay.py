"""Feeding recorded messages (a bag, in log-time order) into a session on several threads.

:class:`ReplayFeeder` is what ``rwhec-calibrate bag`` uses: poses are added on the caller's
thread as they are read; images are examined by ``threads`` workers through a blocking
:class:`~rwhec_ros.session.FairImageQueue`, so nothing is dropped, and the images of one camera
are examined one at a time in log order, each only once the pose after its stamp has been read
(the reader holds it until then). With these two rules the kept pairs are those of the plain
synchronous replay (one thread, images waiting in the session for their pose), whatever the
number of threads: each edge ``(tag, camera)`` sees the same offers in the same order and the
accumulator's decisions per edge depend on nothing else
(:mod:`rwhec_ros.sync.accumulator`). Only the interleaving of different cameras varies, which
changes the order in which the identifiability tracker receives pairs, not the pairs.

An image waits for its pose as live (:mod:`rwhec_ros.session.image_wait`), on the session's clock
(the newest stamp read: the recording's time); at the end of the recording every image still
waiting gets its final answer (:meth:`ReplayFeeder.close`).
"""

from __future__ import annotations

import collections
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from ..messages import stamp_to_ns
from .handlers import MessageHandlers
from .image_queue import FairImageQueue, QueueWorker

__all__ = ["ReplayFeeder"]


class ReplayFeeder:
    """Poses on the caller's thread, images on ``threads`` workers (module docstring).

    Parameters
    ----------
    handlers : MessageHandlers
        Of the session to feed.
    threads : int
        Detection threads; 1 feeds everything synchronously on the caller's thread.
    queue_size : int
        Images queued per camera before :meth:`image` waits (``sync.image_queue_size``).
    on_outcome : callable, optional
        Called as ``on_outcome(camera, msg, outcome)`` with each image's
        :class:`~rwhec_ros.session.outcomes.ImageOutcome` (on the detection thread that
        examined it; the CLI's ``--detections``).
    """

    def __init__(self, handlers: MessageHandlers, *, threads: int, queue_size: int,
                 on_outcome: Callable[[str, Any, Any], None] | None = None) -> None:
        if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
            raise ValueError(f"threads: expected an integer >= 1, got {threads!r}")
        self.handlers = handlers
        self.session = handlers.session
        self.on_outcome = on_outcome
        self.threads = threads
        self.errors: list[BaseException] = []
        self._lock = threading.Lock()
        cameras = self.session.config.camera_names
        self._held = {c: collections.deque() for c in cameras}
        self._queue = None
        self._workers: list[QueueWorker] = []
        if threads > 1:
            self._queue = FairImageQueue(cameras, queue_size, block=True)
            self._workers = [QueueWorker(self._queue, self._examine, name=f"rwhec-replay-{i}",
                                         on_error=self._error).start()
                             for i in range(threads)]

    def pose(self, msg: Any) -> bool:
        """A ``geometry_msgs/PoseStamped`` of the pose source; images it serves go to work."""
        ok = self.handlers.on_pose_stamped(msg)
        if self._queue is not None:
            self._release(final=False)
        return ok

    def image(self, camera: str, msg: Any, *, compressed: bool,
              T_parent_child: np.ndarray | None = None) -> None:
        """An image of ``camera`` (``sensor_msgs/Image``, or ``CompressedImage`` when
        ``compressed``), with the pose at its stamp when it is known (tf)."""
        try:
            arrived = self.session.image_arrival(
                self.session.pose_time(camera, stamp_to_ns(msg.header.stamp)))
        except (ValueError, TypeError, AttributeError):
            arrived = None  # a bad stamp: rejected and counted by the handlers
        item = (msg, compressed, T_parent_child, arrived)
        if self._queue is None:
            self._handle(camera, item)
            return
        if camera not in self._held:
            self._handle(camera, item)  # unknown camera: rejected and counted at once
            return
        self._held[camera].append(item)
        self._release(final=False)

    def close(self, timeout: float | None = None) -> None:
        """Hand over every held image, wait until all are examined, stop the workers; then every
        image still waiting for a pose gets its final answer (no pose comes any more)."""
        if self._queue is not None:
            self._release(final=True)
            self._queue.join(timeout)
            for w in self._workers:
                w.stop()
        self.session.flush_pending()

    def abort(self) -> None:
        """Stop the workers after their current image (Ctrl-C): images still held or queued
        are not examined."""
        for held in self._held.values():
            held.clear()
        for w in self._workers:
            w.stop()

    # --- internals -----------------------------------------------------------------------------
    def _ready(self, camera: str, item: tuple) -> bool:
        msg, _, T, arrived = item
        if T is not None or arrived is None:
            return True  # arrived None: a bad stamp, rejected and counted by the handlers
        return self.session.pose_ready(
            self.session.pose_time(camera, stamp_to_ns(msg.header.stamp)), arrived)

    def _release(self, *, final: bool) -> None:
        """Queue each camera's held images, oldest first, while their pose is there."""
        for camera, held in self._held.items():
            while held and (final or self._ready(camera, held[0])):
                self._queue.put(camera, held.popleft())

    def _examine(self, entry: tuple) -> None:
        camera, item = entry
        self._handle(camera, item)

    def _handle(self, camera: str, item: tuple) -> None:
        msg, compressed, T, arrived = item
        if compressed:
            outcome = self.handlers.on_compressed_image(camera, msg, T, arrived_ns=arrived)
        else:
            outcome = self.handlers.on_image(camera, msg, T, arrived_ns=arrived)
        if self.on_outcome is not None:
            self.on_outcome(camera, msg, outcome)

    def _error(self, exc: BaseException) -> None:
        with self._lock:
            self.errors.append(exc)
