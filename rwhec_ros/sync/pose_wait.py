"""How late the pose stream arrives, and so how long an image may wait for the pose at its stamp.

Through a real transport (DDS, a MultiThreadedExecutor) the pose stream can lag the images by more
than its own period: on a real ROS 2 Jazzy at 8 x 30 Hz images and 200 Hz poses the poses were
27 ms old (p50) when their callback ran, 231 ms (p95), 265 ms at most, the images 29 / 83 ms
(issue 39). An image newer than the newest pose is then not "after the buffer" for good: its pose
is on its way. It should wait as long as the pose stream's measured lateness says, no longer.

**Ages.** :class:`PoseLatency` records, for every pose stored, its *age* at arrival,
``now - stamp``, on the clock of the session (``now``: the node's ROS clock, the log time of a
bag, or, without a clock, the newest stamp received; :mod:`rwhec_ros.session.image_input`). An age
includes any constant offset between the clock and the stamps (another host's clock, a bag played
without ``/clock``): nothing below needs it to be small, only constant. It keeps the smallest and
largest age over the arrivals of the last ``window_ns`` (10 s), in buckets of 100 ms (bounded
memory: at most 101 buckets whatever the pose rate).

**The deadline of an image** stamped ``s`` that arrived at ``t_arr`` (:func:`wait_deadline`):

* a pose that can serve it is stamped at most ``max_gap`` after ``s`` (a later first pose after
  ``s`` leaves a gap longer than ``sync.max_gap_s`` around it: no interpolation), and a pose
  stamped ``p`` arrives by ``p + hi``, ``hi`` the largest age seen; so once the clock passes
  ``s + max_gap + hi + margin`` no pose that could serve the image will come. ``margin =
  max(20 ms, (hi - lo) / 4)``: a quarter of the spread of the ages (the clock offset cancels in
  ``hi - lo``) for lateness a little beyond the window's worst;
* and it never waits longer than ``max_wait`` after its arrival (``sync.max_pose_wait_s``): the
  bound in time, also before any age is known (no pose yet) and when the ages say more.

Which bound ended the wait is the cause an image without a pose is counted by
(``no_pose_at_stamp:wait_timeout`` for ``max_wait``, else what the pose buffer says then:
``after_buffer``, ``gap_too_large``, ``empty``).
"""

from __future__ import annotations

import collections
from dataclasses import dataclass

__all__ = ["PoseLatency", "WaitDeadline", "wait_deadline", "LATENCY_WINDOW_NS",
           "MIN_MARGIN_NS"]

_MS = 1_000_000
#: Arrivals whose ages count (by the session's clock): 10 s.
LATENCY_WINDOW_NS = 10_000 * _MS
#: Bucket width of the window (its resolution in time).
_BUCKET_NS = 100 * _MS
#: Fewest poses in the window before their ages are used (before: only ``max_wait`` bounds).
MIN_SAMPLES = 10
#: Smallest margin added to the largest age [ns].
MIN_MARGIN_NS = 20 * _MS


class PoseLatency:
    """Smallest and largest age ``now - stamp`` of the poses that arrived within the last
    ``window_ns`` of the clock (module docstring). Not thread-safe (the session's lock).

    Parameters
    ----------
    window_ns : int
        Arrivals older than this (on the clock) are forgotten.
    min_samples : int
        :meth:`ages` answers None with fewer poses in the window.
    """

    def __init__(self, window_ns: int = LATENCY_WINDOW_NS, *,
                 min_samples: int = MIN_SAMPLES) -> None:
        if not (isinstance(window_ns, int) and window_ns >= _BUCKET_NS):
            raise ValueError(f"window_ns: expected an integer >= {_BUCKET_NS}, got "
                             f"{window_ns!r}")
        if not (isinstance(min_samples, int) and min_samples >= 1):
            raise ValueError(f"min_samples: expected an integer >= 1, got {min_samples!r}")
        self.window_ns = window_ns
        self.min_samples = min_samples
        self._buckets: collections.deque = collections.deque()  # [start, lo, hi, count]
        self._last_now: int | None = None
        self._summary: tuple[int, int, int] | None = None  # (count, lo, hi); None: stale

    def clear(self) -> None:
        """Forget every age (e.g. after the pose stream jumped to another time line)."""
        self._buckets.clear()
        self._last_now = None
        self._summary = None

    def record(self, stamp_ns: int, now_ns: int) -> None:
        """One pose stamped ``stamp_ns`` arrived at ``now_ns`` (both [ns], same clock). A clock
        that went back by more than a bucket (a simulator reset) forgets what was recorded."""
        if self._last_now is not None and now_ns < self._last_now - _BUCKET_NS:
            self.clear()
        self._last_now = now_ns if self._last_now is None else max(self._last_now, now_ns)
        age = now_ns - stamp_ns
        start = now_ns - now_ns % _BUCKET_NS
        b = self._buckets[-1] if self._buckets else None
        if b is not None and b[0] >= start:  # this bucket (or a clock a little behind it)
            b[1], b[2], b[3] = min(b[1], age), max(b[2], age), b[3] + 1
        else:
            self._buckets.append([start, age, age, 1])
        if self._summary is not None:  # kept up to date without a pass over the buckets
            n, lo, hi = self._summary
            self._summary = (n + 1, min(lo, age), max(hi, age)) if n else (1, age, age)
        self._evict(now_ns)

    def _evict(self, now_ns: int) -> None:
        while self._buckets and self._buckets[0][0] + _BUCKET_NS <= now_ns - self.window_ns:
            self._buckets.popleft()
            self._summary = None

    def ages(self, now_ns: int | None = None) -> tuple[int, int] | None:
        """``(lo, hi)``, the smallest and largest age [ns] over the window (ending at ``now_ns``,
        default the latest arrival), or None with fewer than ``min_samples`` poses in it."""
        if now_ns is not None:
            self._evict(now_ns)
        n, lo, hi = self._summarise()
        return None if n < self.min_samples else (lo, hi)

    def _summarise(self) -> tuple[int, int, int]:
        """``(count, lo, hi)`` over the buckets, recomputed only after a bucket left."""
        if self._summary is None:
            b = self._buckets
            self._summary = ((sum(x[3] for x in b), min(x[1] for x in b), max(x[2] for x in b))
                             if b else (0, 0, 0))
        return self._summary

    def count(self) -> int:
        """Poses in the window."""
        return self._summarise()[0]


@dataclass(frozen=True)
class WaitDeadline:
    """When an image stops waiting for its pose: ``at_ns`` on the session's clock, and whether
    ``max_wait`` (``timeout``) or the pose stream's ages set it."""

    at_ns: int
    timeout: bool


def wait_deadline(stamp_ns: int, arrived_ns: int, ages: tuple[int, int] | None, *,
                  max_gap_ns: int, max_wait_ns: int) -> WaitDeadline:
    """The deadline of an image stamped ``stamp_ns`` that arrived at ``arrived_ns`` (module
    docstring): ``min(arrived + max_wait, stamp + max_gap + hi + margin)``, only the first
    without ``ages`` (:meth:`PoseLatency.ages`)."""
    cap = arrived_ns + max_wait_ns
    if ages is None:
        return WaitDeadline(cap, True)
    lo, hi = ages
    by_ages = stamp_ns + max_gap_ns + hi + max(MIN_MARGIN_NS, (hi - lo) // 4)
    if by_ages < cap:
        return WaitDeadline(by_ages, False)
    return WaitDeadline(cap, True)
