"""A thread-safe rate limit: at most one event per period (the node's ``~/detections``)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

__all__ = ["RateGate"]


class RateGate:
    """Lets one caller through at most every ``1 / rate_hz`` seconds.

    Parameters
    ----------
    rate_hz : float
        Events per second, ``>= 0``; 0 lets nothing through (off).
    clock : callable, optional
        Monotonic seconds (default :func:`time.monotonic`); injectable for tests.
    """

    def __init__(self, rate_hz: float, clock: Callable[[], float] | None = None) -> None:
        rate = float(rate_hz)
        if not (rate >= 0 and rate != float("inf")):
            raise ValueError(f"rate_hz: must be finite and >= 0, got {rate_hz!r}")
        self.period_s = None if rate == 0 else 1.0 / rate
        self._clock = clock if clock is not None else time.monotonic
        self._lock = threading.Lock()
        self._last: float | None = None

    def take(self) -> bool:
        """True when a period has passed since the last True (the slot is then taken)."""
        if self.period_s is None:
            return False
        now = self._clock()
        with self._lock:
            if self._last is not None and now - self._last < self.period_s:
                return False
            self._last = now
            return True
