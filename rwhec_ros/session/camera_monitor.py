"""Per-camera monitoring: images lost in transport (from the stamps' spacing) and the per-camera
rows of ``/diagnostics`` (plain Python; the node publishes the rows).

Transport loss. A camera publishes at a steady rate, so the spacing of its image stamps shows the
publish period even when the subscriber misses messages: with a fraction ``p`` of the messages
lost at random, consecutive *received* stamps are ``k`` periods apart with probability
``(1 - p) p^(k-1)``, so the 25th percentile of the spacings is one period for any ``p`` up to 75 %
(and at most a few periods beyond). :class:`StampRateMonitor` keeps the last ``window`` stamps of
each camera and estimates

* the publish period ``T`` = 25th percentile of the positive stamp spacings,
* the images expected over the window ``span / T + 1`` and the fraction lost
  ``1 - received / expected``,

without any clock of its own (so it works on bag replays and in simulated time alike). A camera
losing more than ``loss_warn_fraction`` (default 20 %) gets a WARN row on ``/diagnostics`` naming
it; the README's "Losing images" section says what to change (reliable QoS, DDS socket buffers,
compressed transport).
"""

from __future__ import annotations

import collections
import threading
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..messages import LEVEL_OK, LEVEL_WARN

__all__ = ["RateEstimate", "StampRateMonitor", "CameraDiagnostics", "LOSS_WARN_FRACTION"]

#: Default fraction of a camera's images lost in transport above which its row is a WARN.
LOSS_WARN_FRACTION = 0.2

_NS = 1_000_000_000
#: A stamp this much older than the newest one restarts the window (a bag played in a loop).
_BACKWARDS_RESET_NS = _NS


@dataclass(frozen=True)
class RateEstimate:
    """Rates of one camera over the monitor's window.

    Attributes
    ----------
    samples : int
        Stamps in the window.
    publish_rate_hz : float
        ``1 / T`` with ``T`` the 25th percentile of the stamp spacings.
    received_rate_hz : float
        ``(samples - 1) / span`` with ``span`` the stamp range of the window.
    lost_fraction : float
        ``1 - samples / (span / T + 1)``, clipped to [0, 1].
    """

    samples: int
    publish_rate_hz: float
    received_rate_hz: float
    lost_fraction: float


class StampRateMonitor:
    """Received image stamps per camera and the loss estimate of the module docstring.

    Thread-safe: :meth:`record` is called from the subscription callbacks.

    Parameters
    ----------
    keys : sequence of hashable
        Camera names.
    window : int
        Stamps kept per camera (>= 3).
    min_samples : int
        Fewer stamps than this give no estimate (``None``).
    """

    def __init__(self, keys: Sequence[Hashable], *, window: int = 100,
                 min_samples: int = 20) -> None:
        if isinstance(window, bool) or not isinstance(window, int) or window < 3:
            raise ValueError(f"window: expected an integer >= 3, got {window!r}")
        if not 3 <= min_samples <= window:
            raise ValueError(f"min_samples: expected 3 <= min_samples <= window, got "
                             f"{min_samples!r}")
        self.min_samples = int(min_samples)
        self._stamps = {k: collections.deque(maxlen=window) for k in keys}
        self._lock = threading.Lock()

    def record(self, key: Hashable, stamp_ns: int) -> None:
        """Note one received image of ``key`` (unknown keys and non-integer stamps ignored)."""
        stamps = self._stamps.get(key)
        if stamps is None or isinstance(stamp_ns, bool) or not isinstance(stamp_ns, int):
            return
        with self._lock:
            if stamps and stamp_ns < stamps[-1] - _BACKWARDS_RESET_NS:
                stamps.clear()
            stamps.append(stamp_ns)

    def estimate(self, key: Hashable) -> RateEstimate | None:
        """The rates of ``key`` over its window, or None with fewer than ``min_samples`` stamps
        (or no spacing: all stamps equal)."""
        with self._lock:
            stamps = np.array(sorted(set(self._stamps.get(key, ()))), dtype=np.int64)
        if stamps.size < self.min_samples:
            return None
        spacing = np.diff(stamps)
        period = float(np.quantile(spacing, 0.25))
        span = float(stamps[-1] - stamps[0])
        expected = span / period + 1.0
        lost = min(1.0, max(0.0, 1.0 - stamps.size / expected))
        return RateEstimate(int(stamps.size), _NS / period, (stamps.size - 1) * _NS / span, lost)


class CameraDiagnostics:
    """The per-camera rows of ``/diagnostics``: what arrived, what the queue dropped, what the
    motion gate skipped, what was searched and used, and whether the transport loses images.

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
    ) -> list[dict[str, Any]]:
        """One row per camera, in the format of :func:`rwhec_ros.messages.diagnostic_rows`.

        ``session_counts``: :meth:`CalibrationSession.camera_counters`; ``queue_stats``:
        :meth:`FairImageQueue.stats` (``received``, ``dropped``, ``queued``). WARN when the
        transport loses more than ``loss_warn_fraction`` of the camera's images, or when the
        queue dropped images since the previous call (detection does not keep up, or the images
        wait for poses that do not come).
        """
        rows = []
        for cam in self.cameras:
            s = session_counts.get(cam, {})
            q = queue_stats.get(cam, {})
            dropped = int(q.get("dropped", 0))
            new_drops = dropped - self._last_dropped.get(cam, 0)
            self._last_dropped[cam] = dropped
            rate = self.monitor.estimate(cam)
            problems = []
            if rate is not None and rate.lost_fraction > self.loss_warn_fraction:
                problems.append(
                    f"receiving {rate.received_rate_hz:.1f} of ~{rate.publish_rate_hz:.1f} "
                    f"images/s: {100 * rate.lost_fraction:.0f} % lost in transport (stamp "
                    "spacing; see the README, 'Losing images')")
            if new_drops > 0:
                problems.append(f"{new_drops} images dropped from the full queue since the last "
                                "report (detection does not keep up, or no pose comes for them)")
            summary = (f"{q.get('received', 0)} received, {s.get('skipped_no_motion', 0)} "
                       f"skipped (no motion), {s.get('detected', 0)} searched, {dropped} dropped, "
                       f"{s.get('pairs_kept', 0)} pairs")
            values = [("received", q.get("received", 0)), ("dropped", dropped),
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
