"""Images waiting for the pose at their stamp: the live session's part (plain Python).

An image can only be used with the pose ``A`` at its stamp, interpolated between two poses that
bracket it. Through a real transport the pose stream lags the images (issue 39: up to 265 ms at
200 Hz poses, far more than one pose period), so an image newer than the newest pose, one in a gap
of the pose buffer (poses reordered by the executor), or one before any pose *waits*, undecoded,
until a pose brackets its stamp or its deadline passes (:func:`~rwhec_ros.sync.pose_wait.
wait_deadline`: the pose stream's measured lateness, at most ``sync.max_pose_wait_s`` after the
image arrived). Only then is its lookup final. The node holds such images in its queue (asking
:meth:`ImageWait.pose_ready`); direct callers of ``add_image`` have them held in the session,
within ``sync.max_waiting_mb`` (the oldest then gets its final answer at once).

**The session's clock** (``now``, integer ns): the ``clock`` the session was given (the node's
ROS clock, which follows ``/clock`` in simulation), else the newest stamp received, image or pose
(feeding in stamp or log order, as the tests and ``rwhec-calibrate bag`` do, makes it the time of
the recording). Arrival times and the ages of the poses are read on it.

**An image that finally has no pose** is counted ``no_pose_at_stamp:<cause>`` (and per camera,
:meth:`ImageWait.no_pose_counts`); :data:`NO_POSE_CAUSES` says what each cause means and which
parameter changes it (the node's ``/diagnostics`` names them when a camera loses more than a few
percent of its images this way, :mod:`rwhec_ros.session.pose_loss`).
"""

from __future__ import annotations

import collections
from typing import Any

import numpy as np

from ..sync.at_rest import AtRestRule, at_rest_lookup, waits_at_rest
from ..sync.buffer import LookupStatus
from ..sync.pose_wait import PoseLatency, WaitDeadline, wait_deadline

__all__ = ["ImageWait", "NO_POSE_CAUSES", "NO_POSE_PREFIX"]

NO_POSE_PREFIX = "no_pose_at_stamp:"
_NS = 1_000_000_000
_MB = 1_000_000

#: Why an image finally had no pose: cause -> (what happened, the parameter to look at).
NO_POSE_CAUSES = {
    "wait_timeout": ("the pose stream lagged the image by more than sync.max_pose_wait_s",
                     "sync.max_pose_wait_s"),
    "wait_memory": ("the images waiting for their pose filled sync.max_waiting_mb",
                    "sync.max_waiting_mb"),
    "after_buffer": ("the pose stream stopped or paused for longer than sync.max_gap_s after "
                     "the newest pose", "sync.max_gap_s"),
    "gap_too_large": ("the poses around the image stamp are more than sync.max_gap_s apart",
                      "sync.max_gap_s"),
    "before_buffer": ("the image is older than the oldest pose held (the images lag the poses "
                      "by more than the pose buffer holds)", "sync.pose_buffer_size"),
    "empty": ("no pose had arrived", "pose_source.topic"),
}


class ImageWait:
    """Mixin of :class:`~rwhec_ros.session.CalibrationSession` (through
    :class:`~rwhec_ros.session.image_input.ImageInput`): waiting for poses (module docstring).
    It uses the session's ``_lock``, ``_buffer``, ``_latency``, ``_pending``,
    ``_pending_bytes``, ``_proxy_now``, ``_clock``, ``_no_pose``, ``_counters``,
    ``_camera_counts`` and ``config``; the image path's ``_examine`` and ``_reject``."""

    _clock: Any
    _latency: PoseLatency

    # --- public --------------------------------------------------------------------------------
    def now_ns(self) -> int:
        """The session's clock [ns] (module docstring)."""
        with self._lock:
            return self._now_locked()

    def image_arrival(self, stamp_ns: Any) -> int:
        """An image stamped ``stamp_ns`` arrives now: its arrival time on the session's clock
        (without a clock the stamp advances the clock). Call it when the image is received, keep
        the answer with the image and give it to :meth:`pose_ready` and ``add_image``."""
        stamp = _stamp(stamp_ns)
        with self._lock:
            if self._clock is None and stamp is not None:
                self._proxy_now = max(self._proxy_now, stamp)
            return self._now_locked()

    def pose_ready(self, stamp_ns: Any, arrived_ns: int | None = None) -> bool:
        """True when an image stamped ``stamp_ns`` (arrived at ``arrived_ns``, default now) need
        not wait for a pose now: a pose brackets its stamp, its lookup can never succeed, or its
        deadline has passed (its lookup is then final). An invalid stamp too, so that it is
        rejected at once. The node's image queue holds images back until then, so that they are
        gated and examined in order without waiting in the session."""
        stamp = _stamp(stamp_ns)
        if stamp is None:
            return True
        with self._lock:
            arrived = self._now_locked() if arrived_ns is None else int(arrived_ns)
            return not self._waits(stamp, arrived)

    def record_no_pose(self, camera: str, cause: str) -> None:
        """Count an image of ``camera`` given up outside the session while it waited for its pose
        (the node's queue dropping the oldest waiting image: ``"wait_memory"``)."""
        with self._lock:
            self._count_no_pose(str(camera), str(cause))

    def no_pose_counts(self) -> dict[str, dict[str, int]]:
        """Per camera (configuration order): the images that finally had no pose, by cause
        (:data:`NO_POSE_CAUSES`; only causes seen)."""
        with self._lock:
            return {c: dict(self._no_pose.get(c, {})) for c in self.config.camera_names}

    def pose_wait_values(self) -> list[tuple[str, str]]:
        """What the waiting rests on, for ``/diagnostics``: the smallest and largest age of the
        poses over the last 10 s (``now - stamp``, clock offset included) and how long after its
        stamp a new image may wait now (``image_wait_s``)."""
        with self._lock:
            now = self._now_locked()
            ages = self._latency.ages(now)
            wait = self._deadline(now, now)
        out = [("image_wait_s", f"{(wait.at_ns - now) / _NS:.3f}"
                + (" (sync.max_pose_wait_s)" if wait.timeout else ""))]
        if ages is not None:
            out += [("pose_age_min_s", f"{ages[0] / _NS:.3f}"),
                    ("pose_age_max_s", f"{ages[1] / _NS:.3f}")]
        return out

    def flush_pending(self) -> int:
        """Give every image waiting in the session its final answer now (the end of a recording:
        no pose will come any more); returns how many there were."""
        with self._lock:
            items = list(self._pending)
            self._pending.clear()
            self._pending_bytes = 0
        for item in items:
            self._finish_pending(item, final=True)
        return len(items)

    # --- internals (lock held unless said otherwise) --------------------------------------------
    def _now_locked(self) -> int:
        return int(self._clock()) if self._clock is not None else self._proxy_now

    def _note_pose(self, stamp: int, stored: bool, resets_before: int) -> None:
        """After a pose was offered to the buffer: its age (when stored), the clock without a
        clock, and a fresh start of both after a reset of the buffer (another time line)."""
        if self._buffer.resets != resets_before:
            self._latency.clear()
            if self._clock is None:
                self._proxy_now = stamp
        if not stored:
            return
        if self._clock is None:
            self._proxy_now = max(self._proxy_now, stamp)
        self._latency.record(stamp, self._now_locked())

    def _deadline(self, stamp: int, arrived: int) -> WaitDeadline:
        sync = self.config.sync
        gap = max(sync.max_gap_s, sync.extrapolation_tolerance_s)
        return wait_deadline(stamp, arrived, self._latency.ages(self._now_locked()),
                             max_gap_ns=int(round(gap * _NS)),
                             max_wait_ns=int(round(sync.max_pose_wait_s * _NS)))

    def _waits(self, stamp: int, arrived: int) -> bool:
        """The image should (still) wait for a later pose: its lookup is not final yet (no pose
        brackets it, and it is not older than the buffer) and its deadline has not passed."""
        status = self._buffer.lookup_status(stamp)
        if status is LookupStatus.BEFORE_BUFFER:
            return False
        newest = self._buffer.newest_ns
        if newest is None:  # no pose yet: wait until the deadline
            return self._now_locked() < self._deadline(stamp, arrived).at_ns
        if status is LookupStatus.OK and stamp <= newest:
            return False
        rule = AtRestRule.from_sync(self.config.sync)
        if stamp <= newest and at_rest_lookup(self._buffer, stamp, rule) is not None:
            return False  # bracketed by two samples of the stream at rest: final
        now = self._now_locked()
        if now < self._deadline(stamp, arrived).at_ns:
            return True
        # stop-and-go (:mod:`rwhec_ros.sync.at_rest`): the stream may be at rest, its next sample
        # up to ``sync.at_rest_max_gap_s`` after the newest: wait for it until then
        return waits_at_rest(self._buffer, stamp, rule) and now < newest + rule.max_gap_ns

    def _pose_at(self, stamp: int, arrived: int, *, final: bool,
                 cause: str = "") -> tuple[str, np.ndarray | None, str]:
        """``("wait", None, "")``, ``("ok", A, "")`` or ``("rejected", None, reason)`` for an
        image at ``stamp``; ``final``: never wait; ``cause``: of a rejection (else the one that
        ended the wait)."""
        if not final and self._waits(stamp, arrived):
            return "wait", None, ""
        A = self._buffer.lookup(stamp)
        if A is not None:
            return "ok", A, ""
        A = at_rest_lookup(self._buffer, stamp, AtRestRule.from_sync(self.config.sync))
        if A is not None:  # stop-and-go: the stream was at rest across the image
            self._counters["pose_at_rest"] += 1
            return "ok", A, ""
        return "rejected", None, NO_POSE_PREFIX + (cause or self._no_pose_cause(stamp, arrived))

    def _no_pose_cause(self, stamp: int, arrived: int) -> str:
        """Why an image whose lookup failed has no pose (:data:`NO_POSE_CAUSES`)."""
        status = self._buffer.lookup_status(stamp)
        if status in (LookupStatus.BEFORE_BUFFER, LookupStatus.EMPTY):
            return status.value
        deadline = self._deadline(stamp, arrived)
        if deadline.timeout and self._now_locked() >= deadline.at_ns:
            return "wait_timeout"
        return "after_buffer" if status is LookupStatus.WAIT else status.value

    def _count_no_pose(self, camera: str, cause: str) -> None:
        self._counters[NO_POSE_PREFIX + cause] += 1
        if camera in self._camera_counts:
            self._camera_counts[camera]["no_pose"] += 1
            self._camera_counts[camera]["rejected"] += 1
            self._no_pose.setdefault(camera, collections.Counter())[cause] += 1

    def _hold(self, camera: str, stamp: int, image, intrinsics, arrived: int) -> list[tuple]:
        """Keep an image waiting in the session; returns the oldest waiting ones that no longer
        fit in ``sync.max_waiting_mb`` (to be answered at once, lock NOT held then)."""
        size = _image_bytes(image, intrinsics)
        self._pending.append((camera, stamp, image, intrinsics, arrived, size))
        self._pending_bytes += size
        self._counters["images_pending"] += 1
        budget = self.config.sync.max_waiting_mb * _MB
        out = []
        while self._pending_bytes > budget and len(self._pending) > 1:
            item = self._pending.popleft()
            self._pending_bytes -= item[5]
            out.append(item)
        return out

    def _take_ready_pending(self) -> list[tuple]:
        """Remove the waiting images that need not wait any more, oldest first, as
        ``(camera, stamp, image, intrinsics, A, reason)``."""
        ready, still = [], collections.deque()
        for item in self._pending:
            state, A, reason = self._pose_at(item[1], item[4], final=False)
            if state == "wait":
                still.append(item)
            else:
                ready.append((*item[:4], A, reason))
                self._pending_bytes -= item[5]
        self._pending = still
        return ready

    def _serve_pending(self) -> None:
        """Answer the waiting images that need not wait any more (lock NOT held)."""
        if not self._pending:
            return
        with self._lock:
            ready = self._take_ready_pending()
        for item in ready:
            self._finish_pending(item)

    def _finish_pending(self, item: tuple, *, final: bool = False, cause: str = ""):
        """Examine (or reject) one image that waited for its pose (lock NOT held); ``final``:
        ``item`` is a waiting one, answered with what the buffer has now (``cause`` of a
        rejection)."""
        if final:
            camera, stamp, image, intrinsics, arrived, _ = item
            with self._lock:
                _, A, reason = self._pose_at(stamp, arrived, final=True, cause=cause)
        else:
            camera, stamp, image, intrinsics, A, reason = item
        if A is None:
            return self._reject(camera, stamp, reason)
        return self._examine(camera, stamp, image, intrinsics, A)


def _stamp(value: Any) -> int | None:
    """A stamp as a non-negative int, or None when it is not one."""
    try:
        if isinstance(value, bool):
            return None
        out = int(value)
        return out if out == value and out >= 0 else None
    except (TypeError, ValueError, OverflowError):
        return None


def _image_bytes(image, intrinsics) -> int:
    """Bytes an image holds while it waits: an array's, a lazy image's ``nbytes`` (the handlers'
    message size), else the decoded size (one byte per pixel)."""
    n = getattr(image, "nbytes", None)
    if isinstance(n, (int, np.integer)) and n >= 0:
        return int(n)
    return int(intrinsics.width) * int(intrinsics.height)
