"""Per-camera monitoring: images lost in transport (from the stamps' spacing) and the per-camera
rows of ``/diagnostics`` (plain Python; the node publishes the rows).

Transport loss. A camera publishes at a steady rate, so the spacing of its image stamps shows the
publish period even when the subscriber misses messages: with a fraction ``p`` of the messages
lost at random, consecutive *received* stamps are ``k`` periods apart with probability
``(1 - p) p^(k-1)``. :class:`StampRateMonitor` keeps the stamps of each camera over the last
``window_ns`` (20 s) of stamps and estimates, without any clock of its own (so it works on bag
replays and in simulated time alike):

* the publish period ``T``: the stamps are cut into segments of 2 s; in each segment with at
  least 4 spacings, the spacing below which lie 5 % of the segment's *time* (a quantile of the
  spacings weighted by their length); ``T`` is the median over the segments. Weighted by time, the
  one-period spacings hold a share ``(1 - p)^2`` of it, so ``T`` is one period for a loss up to
  about 3/4 (beyond, ``T`` reads two periods in some segments and the loss reads lower, still far
  above the warning level). **Bursts** cannot blow it up (issue 39: 500 images in 1.3 s on one
  camera read ``publish_rate_hz: 1907.99, lost_in_transport: 0.989``): a burst's many short
  spacings hold little time within its segments, and a burst shorter than half the window leaves
  the median to the steady segments;
* the images expected, ``1 + sum(max(1, round(d / T)))`` over the spacings ``d`` (a spacing of
  ``k`` periods means ``k - 1`` lost; spacings shorter than a period, as in a burst, count one:
  no loss is invented inside a burst), and the fraction lost ``1 - received / expected``.

A camera losing more than ``loss_warn_fraction`` (default 20 %) gets a WARN row on
``/diagnostics`` naming it; the README's "Losing images" section says what to change (reliable
QoS, DDS socket buffers, compressed transport). So does a camera whose images more than a few
percent had no pose at their stamp (:mod:`rwhec_ros.session.pose_loss`), naming the cause and the
parameter.
"""

from __future__ import annotations

import collections
import threading
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..messages import LEVEL_OK, LEVEL_WARN
from .pose_loss import NoPoseWindow

__all__ = ["RateEstimate", "StampRateMonitor", "CameraDiagnostics", "LOSS_WARN_FRACTION"]

#: Default fraction of a camera's images lost in transport above which its row is a WARN.
LOSS_WARN_FRACTION = 0.2

_NS = 1_000_000_000
#: A stamp this much older than the newest one is stale (a late message: ignored) ...
_BACKWARDS_RESET_NS = _NS
#: ... and this many consecutive stale stamps restart the window (a bag played in a loop).
_BACKWARDS_RESET_SAMPLES = 5
#: Stamps of the window [ns], segments of the period estimate [ns], spacings per segment.
WINDOW_NS = 20 * _NS
_SEGMENT_NS = 2 * _NS
_MIN_SEGMENT_SPACINGS = 4
#: Share of a segment's time below the period estimate.
_TIME_QUANTILE = 0.05


@dataclass(frozen=True)
class RateEstimate:
    """Rates of one camera over the monitor's window.

    Attributes
    ----------
    samples : int
        Stamps in the window.
    publish_rate_hz : float
        ``1 / T`` with ``T`` the period estimate of the module docstring.
    received_rate_hz : float
        ``(samples - 1) / span`` with ``span`` the stamp range of the window.
    lost_fraction : float
        ``1 - samples / expected`` (module docstring), clipped to [0, 1].
    """

    samples: int
    publish_rate_hz: float
    received_rate_hz: float
    lost_fraction: float


def _time_quantile(spacing: np.ndarray, q: float) -> float:
    """The spacing below which lies a share ``q`` of the total time of ``spacing`` (> 0)."""
    d = np.sort(spacing)
    share = np.cumsum(d) / d.sum()
    return float(d[min(int(np.searchsorted(share, q)), d.size - 1)])


def publish_period(stamps: np.ndarray) -> float:
    """The publish period [ns] of sorted distinct ``stamps`` (module docstring)."""
    spacing = np.diff(stamps)
    segment = (stamps[1:] - stamps[0]) // _SEGMENT_NS
    periods = []
    for k in np.unique(segment):
        d = spacing[segment == k]
        if d.size >= _MIN_SEGMENT_SPACINGS:
            periods.append(_time_quantile(d, _TIME_QUANTILE))
    if not periods:
        return _time_quantile(spacing, _TIME_QUANTILE)
    return float(np.median(periods))


class StampRateMonitor:
    """Received image stamps per camera and the loss estimate of the module docstring.

    Thread-safe: :meth:`record` is called from the subscription callbacks.

    Parameters
    ----------
    keys : sequence of hashable
        Camera names.
    window : int
        Stamps kept per camera at most (>= 3), besides the ``window_ns`` span.
    min_samples : int
        Fewer stamps than this give no estimate (``None``).
    window_ns : int
        Stamps older than the newest by more than this [ns] leave the window.
    """

    def __init__(self, keys: Sequence[Hashable], *, window: int = 2000,
                 min_samples: int = 20, window_ns: int = WINDOW_NS) -> None:
        if isinstance(window, bool) or not isinstance(window, int) or window < 3:
            raise ValueError(f"window: expected an integer >= 3, got {window!r}")
        if not 3 <= min_samples <= window:
            raise ValueError(f"min_samples: expected 3 <= min_samples <= window, got "
                             f"{min_samples!r}")
        if not window_ns > 0:
            raise ValueError(f"window_ns: must be > 0, got {window_ns!r}")
        self.min_samples = int(min_samples)
        self.window_ns = int(window_ns)
        self._stamps = {k: collections.deque(maxlen=window) for k in keys}
        self._stale = dict.fromkeys(keys, 0)
        self._lock = threading.Lock()

    def record(self, key: Hashable, stamp_ns: int) -> None:
        """Note one received image of ``key`` (unknown keys and non-integer stamps ignored)."""
        stamps = self._stamps.get(key)
        if stamps is None or isinstance(stamp_ns, bool) or not isinstance(stamp_ns, int):
            return
        with self._lock:
            if stamps and stamp_ns < stamps[-1] - _BACKWARDS_RESET_NS:
                self._stale[key] += 1
                if self._stale[key] < _BACKWARDS_RESET_SAMPLES:
                    return
                stamps.clear()
            self._stale[key] = 0
            stamps.append(stamp_ns)

    def estimate(self, key: Hashable) -> RateEstimate | None:
        """The rates of ``key`` over its window, or None with fewer than ``min_samples`` stamps
        (or no spacing: all stamps equal)."""
        with self._lock:
            stamps = np.array(sorted(set(self._stamps.get(key, ()))), dtype=np.int64)
        if stamps.size:
            stamps = stamps[stamps >= stamps[-1] - self.window_ns]
        if stamps.size < self.min_samples:
            return None
        period = publish_period(stamps)
        spacing = np.diff(stamps)
        expected = 1.0 + float(np.maximum(1.0, np.round(spacing / period)).sum())
        span = float(stamps[-1] - stamps[0])
        lost = min(1.0, max(0.0, 1.0 - stamps.size / expected))
        return RateEstimate(int(stamps.size), _NS / period, (stamps.size - 1) * _NS / span, lost)


class CameraDiagnostics:
    """The per-camera rows of ``/diagnostics``: what arrived, what the queue dropped, what the
    motion gate skipped, what was searched and used, whether the transport loses images, and
    whether images finally had no pose at their stamp (:attr:`no_pose`, a
    :class:`~rwhec_ros.session.pose_loss.NoPoseWindow` over the last 10 calls of :meth:`rows`;
    its :meth:`~rwhec_ros.session.pose_loss.NoPoseWindow.problem` of all cameras is the session
    row's).

    Parameters
    ----------
    cameras : sequence of str
    monitor : StampRateMonitor, optional
        Default: a new one over ``cameras`` (fed through :meth:`record`).
    loss_warn_fraction : float
        WARN above this estimated transport loss.
    """

    def __init__(self, cameras: Sequence[str], monitor: StampRateMonitor | None = None, *,
                 loss_warn_fraction: float = LOSS_WARN_FRACTION) -> None:
        if not 0.0 < loss_warn_fraction < 1.0:
            raise ValueError(f"loss_warn_fraction: expected a value in (0, 1), got "
                             f"{loss_warn_fraction!r}")
        self.cameras = tuple(cameras)
        self.monitor = monitor if monitor is not None else StampRateMonitor(self.cameras)
        self.loss_warn_fraction = float(loss_warn_fraction)
        self.no_pose = NoPoseWindow(self.cameras)
        self._last_dropped: dict[str, int] = {}

    def record(self, camera: str, stamp_ns: int) -> None:
        """An image of ``camera`` arrived (call it before queueing)."""
        self.monitor.record(camera, stamp_ns)

    def rows(
        self,
        session_counts: Mapping[str, Mapping[str, int]],
        queue_stats: Mapping[str, Mapping[str, int]],
        *,
        prefix: str,
        hardware_id: str = "",
        no_pose: Mapping[str, Mapping[str, int]] | None = None,
    ) -> list[dict[str, Any]]:
        """One row per camera, in the format of :func:`rwhec_ros.messages.diagnostic_rows`.

        ``session_counts``: :meth:`CalibrationSession.camera_counters`; ``queue_stats``:
        :meth:`FairImageQueue.stats` (``received``, ``dropped``, ``dropped_memory``,
        ``queued``); ``no_pose``: :meth:`CalibrationSession.no_pose_counts`. WARN when the
        transport loses more than ``loss_warn_fraction`` of the camera's images, when the queue
        dropped images from the camera's full backlog since the previous call (detection does
        not keep up), or when more than a few percent of its images had no pose at their stamp
        over the last reports (:attr:`no_pose`).
        """
        if no_pose is not None:
            self.no_pose.update({c: int(queue_stats.get(c, {}).get(
                "received", session_counts.get(c, {}).get("images", 0))) for c in self.cameras},
                no_pose)
        rows = []
        for cam in self.cameras:
            s = session_counts.get(cam, {})
            q = queue_stats.get(cam, {})
            dropped = int(q.get("dropped", 0))
            backlog = dropped - int(q.get("dropped_memory", 0))
            new_drops = backlog - self._last_dropped.get(cam, 0)
            self._last_dropped[cam] = backlog
            rate = self.monitor.estimate(cam)
            problems = []
            if rate is not None and rate.lost_fraction > self.loss_warn_fraction:
                problems.append(
                    f"receiving {rate.received_rate_hz:.1f} of ~{rate.publish_rate_hz:.1f} "
                    f"images/s: {100 * rate.lost_fraction:.0f} % lost in transport (stamp "
                    "spacing; see the README, 'Losing images')")
            if new_drops > 0:
                problems.append(f"{new_drops} images dropped from the full queue since the last "
                                "report (detection does not keep up: sync.detection_threads, "
                                "sync.image_queue_size)")
            if no_pose is not None:
                problems += [p for p in [self.no_pose.problem(cam)] if p]
            summary = (f"{q.get('received', 0)} received, {s.get('skipped_no_motion', 0)} "
                       f"skipped (no motion), {s.get('detected', 0)} searched, {dropped} dropped, "
                       + (f"{s.get('no_pose', 0)} without a pose, " if "no_pose" in s else "")
                       + f"{s.get('pairs_kept', 0)} pairs")
            values = [("received", q.get("received", 0)), ("dropped", dropped),
                      ("dropped_memory", q.get("dropped_memory", 0)),
                      ("queued", q.get("queued", 0))]
            values += [(k, v) for k, v in s.items() if k != "images"]
            if rate is not None:
                values += [("publish_rate_hz", f"{rate.publish_rate_hz:.2f}"),
                           ("received_rate_hz", f"{rate.received_rate_hz:.2f}"),
                           ("lost_in_transport", f"{rate.lost_fraction:.3f}")]
            rows.append({
                "name": f"{prefix}: camera {cam}",
                "level": LEVEL_WARN if problems else LEVEL_OK,
                "message": "; ".join(problems + [summary]),
                "hardware_id": hardware_id,
                "values": [(str(k), str(v)) for k, v in values],
            })
        return rows
