"""A bounded, time-ordered buffer of one pose stream, queried at image stamps.

Stamps are integer nanoseconds everywhere (as in ``message_filters``); poses are 4x4 rigid
transforms ``T_a_b`` of one fixed pair of frames (e.g. ``T_world_base`` from motion capture). The
ROS layer converts messages to ``(stamp_ns, T)``; nothing here knows a message type.

Behaviour on the live path (never raises on bad data, every event is counted):

* out-of-order samples are inserted in stamp order (``"out_of_order"``);
* a sample whose stamp is already present is dropped, the first one wins (``"duplicate"``);
* a sample more than ``backwards_jump_ns`` older than the newest one is *stale*. One stale sample
  (a late message, a stray stamp) is dropped and counted (``"dropped_stale"``), the buffer kept.
  Only a *persistent* backwards jump resets the buffer: ``backwards_jump_samples`` consecutive
  valid samples all stale (nothing newer in between), i.e. the stream now lives on an earlier
  time line (a bag played in a loop, a simulator reset). Then the buffer is cleared and that run
  of samples becomes its content (``"reset_backwards_jump"``). Until the run is that long its
  samples are held aside (not looked up); a sample that is not stale ends the run and the run's
  samples are dropped (``"dropped_stale"``, counted then);
* when full, the oldest sample is evicted (``"evicted"``); a sample older than everything in a
  full buffer is dropped (``"dropped_too_old"``);
* a transform that is not a finite rigid transform is rejected by reason (``"rejected_*"``);
  ``add(..., strict=True)`` raises ``ValueError`` instead, for offline use.

:meth:`PoseBuffer.lookup` interpolates with :func:`~rwhec_ros.sync.interpolation.interpolate_se3`
between the two bracketing samples when they are at most ``max_gap_ns`` apart. A stamp that
cannot be interpolated (outside the buffer, or inside a gap larger than ``max_gap_ns``) but lies
within ``extrapolation_tol_ns`` of a sample gets that nearest sample unchanged (zero-order hold;
no extrapolation of motion). :meth:`PoseBuffer.lookup_status` tells a caller whether an image
stamp that cannot be served yet is worth queueing until newer poses arrive (``WAIT``).

Not thread-safe: the caller serialises access (e.g. one lock in the live session).

Promise: without eviction or reset, the answer of ``lookup`` depends only on the *set* of samples
held, not on the order in which they were added.
"""

from __future__ import annotations

import bisect
import numbers
from enum import Enum

import numpy as np

from ..core.problem import DEFAULT_ROTATION_TOL
from .interpolation import interpolate_se3

__all__ = ["LookupStatus", "PoseBuffer", "BACKWARDS_JUMP_SAMPLES"]

#: Consecutive stale samples that make a persistent backwards jump (module docstring): at the
#: usual pose rates (100-1000 Hz) 5-50 ms of a new time line, and no plausible run of late
#: messages (they arrive between samples of the current time line, which end the run).
BACKWARDS_JUMP_SAMPLES = 5


class LookupStatus(str, Enum):
    """What :meth:`PoseBuffer.lookup` would do for a stamp right now."""

    #: A pose is available (interpolated, exact sample, or nearest sample within tolerance).
    OK = "ok"
    #: Newer than the newest sample but within ``max_gap_ns`` of it: poses may still arrive,
    #: queue the image and retry.
    WAIT = "wait"
    #: The buffer holds no sample yet (startup): the caller may queue and retry.
    EMPTY = "empty"
    #: Older than the oldest sample (beyond the tolerance): will never succeed.
    BEFORE_BUFFER = "before_buffer"
    #: Newer than the newest sample by more than ``max_gap_ns``: give up.
    AFTER_BUFFER = "after_buffer"
    #: Between two samples more than ``max_gap_ns`` apart (and not within the tolerance of
    #: either): will never succeed.
    GAP_TOO_LARGE = "gap_too_large"

    @property
    def retry(self) -> bool:
        """True when a later lookup may succeed (``WAIT`` or ``EMPTY``)."""
        return self in (LookupStatus.WAIT, LookupStatus.EMPTY)


_ADD_COUNTERS = (
    "added",
    "out_of_order",
    "duplicate",
    "evicted",
    "dropped_too_old",
    "reset_backwards_jump",
    "dropped_stale",
    "rejected_bad_stamp",
    "rejected_shape",
    "rejected_non_finite",
    "rejected_not_rigid",
)
_LOOKUP_COUNTERS = (
    "lookup_interpolated",
    "lookup_exact",
    "lookup_nearest",
    "lookup_empty",
    "lookup_before_buffer",
    "lookup_after_buffer",
    "lookup_gap_too_large",
)


def _check_int(name: str, value: object, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name}: expected an integer, got {value!r}")
    if int(value) < minimum:
        raise ValueError(f"{name}: must be >= {minimum}, got {value!r}")
    return int(value)


class PoseBuffer:
    """Bounded buffer of ``(stamp_ns, T)`` samples of one pose stream.

    Parameters
    ----------
    capacity : int
        Maximum number of samples held (>= 2); the oldest is evicted when full. Memory is about
        ``capacity * 310`` bytes (measured with ``tracemalloc``: a (4, 4) float64 array with its
        header, a Python int, two list slots), 0.6 MB for the default 2000.
    max_gap_ns : int
        Largest stamp difference [ns] between two samples that are interpolated.
    extrapolation_tol_ns : int
        A stamp this close [ns] to a sample it cannot be interpolated around gets that sample.
    backwards_jump_ns : int
        A sample older than the newest one by more than this [ns] is stale (module docstring).
    backwards_jump_samples : int
        This many consecutive stale samples (>= 1) are a persistent backwards jump: the buffer is
        reset to them. 1 resets on any stale sample (the behaviour before issue 39).
    rotation_tol : float
        Tolerance on ``max|R^T R - I|``, ``|det R - 1|`` and the last row ``[0, 0, 0, 1]``.
    """

    def __init__(
        self,
        capacity: int = 2000,
        max_gap_ns: int = 100_000_000,
        extrapolation_tol_ns: int = 5_000_000,
        *,
        backwards_jump_ns: int = 1_000_000_000,
        backwards_jump_samples: int = BACKWARDS_JUMP_SAMPLES,
        rotation_tol: float = DEFAULT_ROTATION_TOL,
    ) -> None:
        self.capacity = _check_int("capacity", capacity, 2)
        self.max_gap_ns = _check_int("max_gap_ns", max_gap_ns, 1)
        self.extrapolation_tol_ns = _check_int("extrapolation_tol_ns", extrapolation_tol_ns, 0)
        self.backwards_jump_ns = _check_int("backwards_jump_ns", backwards_jump_ns, 1)
        self.backwards_jump_samples = _check_int("backwards_jump_samples",
                                                 backwards_jump_samples, 1)
        if not (np.isfinite(rotation_tol) and rotation_tol > 0):
            raise ValueError(f"rotation_tol: must be finite and > 0, got {rotation_tol!r}")
        self.rotation_tol = float(rotation_tol)
        self._stamps: list[int] = []
        self._poses: list[np.ndarray] = []
        self._stale: list[tuple[int, np.ndarray]] = []  # the current run of stale samples
        self._counters = dict.fromkeys(_ADD_COUNTERS + _LOOKUP_COUNTERS, 0)

    # --- state ---------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self._stamps)

    @property
    def oldest_ns(self) -> int | None:
        """Stamp of the oldest sample, ``None`` when empty."""
        return self._stamps[0] if self._stamps else None

    @property
    def newest_ns(self) -> int | None:
        """Stamp of the newest sample, ``None`` when empty."""
        return self._stamps[-1] if self._stamps else None

    def stamps(self) -> np.ndarray:
        """Stamps held, ascending, shape (n,) int64."""
        return np.array(self._stamps, dtype=np.int64)

    def clear(self) -> None:
        """Drop every sample (counters are kept)."""
        self._stamps.clear()
        self._poses.clear()
        self._stale.clear()

    @property
    def resets(self) -> int:
        """Resets by a persistent backwards jump so far (``"reset_backwards_jump"``)."""
        return self._counters["reset_backwards_jump"]

    def counters(self) -> dict[str, int]:
        """A copy of the event counters (fixed keys, all present from the start)."""
        return dict(self._counters)

    # --- input ---------------------------------------------------------------------------------
    def _validate(self, stamp_ns: object, T: object) -> tuple[str, str] | None:
        """``(counter, message)`` describing why the sample is invalid, or ``None``."""
        if isinstance(stamp_ns, bool) or not isinstance(stamp_ns, numbers.Integral):
            return "rejected_bad_stamp", f"stamp_ns: expected integer nanoseconds, got {stamp_ns!r}"
        if int(stamp_ns) < 0:
            return "rejected_bad_stamp", f"stamp_ns: must be >= 0, got {stamp_ns!r}"
        try:
            M = np.asarray(T, dtype=float)
        except (TypeError, ValueError):
            return "rejected_shape", f"T at stamp {stamp_ns}: not a numeric array: {T!r}"
        if M.shape != (4, 4):
            return "rejected_shape", f"T at stamp {stamp_ns}: expected shape (4, 4), got {M.shape}"
        if not np.isfinite(M).all():
            return "rejected_non_finite", f"T at stamp {stamp_ns}: non-finite value {M.tolist()}"
        R = M[:3, :3]
        last = float(np.abs(M[3] - np.array([0.0, 0.0, 0.0, 1.0])).max())
        orth = float(np.abs(R.T @ R - np.eye(3)).max())
        det = float(np.linalg.det(R))
        if max(last, orth, abs(det - 1.0)) > self.rotation_tol:
            return (
                "rejected_not_rigid",
                f"T at stamp {stamp_ns}: not a rigid transform (max |R^T R - I| = {orth:.3g}, "
                f"det R = {det:.6g}, last row {M[3].tolist()}; tolerance {self.rotation_tol:g})",
            )
        return None

    def add(self, stamp_ns: int, T: np.ndarray, *, strict: bool = False) -> bool:
        """Insert one sample; returns True when it is now held.

        Parameters
        ----------
        stamp_ns : int
            Sample stamp [ns], a non-negative integer.
        T : ndarray, shape (4, 4)
            The pose at ``stamp_ns`` (copied).
        strict : bool
            Raise ``ValueError`` for an invalid stamp or transform instead of counting it.
            Duplicates, out-of-order and stale samples and resets are stream behaviour and
            never raise. A stale sample held aside returns False.
        """
        problem = self._validate(stamp_ns, T)
        if problem is not None:
            if strict:
                raise ValueError(problem[1])
            self._counters[problem[0]] += 1
            return False
        stamp = int(stamp_ns)
        pose = np.array(T, dtype=float)
        if self._stamps and stamp < self._stamps[-1] - self.backwards_jump_ns:
            return self._add_stale(stamp, pose)
        if self._stale:  # a sample of the current time line: the stale run was not a jump
            self._counters["dropped_stale"] += len(self._stale)
            self._stale.clear()
        return self._insert(stamp, pose)

    def _add_stale(self, stamp: int, pose: np.ndarray) -> bool:
        """A stale sample (module docstring): held aside; the run of ``backwards_jump_samples``
        consecutive ones resets the buffer to that run."""
        self._stale.append((stamp, pose))
        if len(self._stale) < self.backwards_jump_samples:
            return False
        run = self._stale
        self._stale = []
        self._stamps.clear()
        self._poses.clear()
        self._counters["reset_backwards_jump"] += 1
        for s, T in run:
            self._insert(s, T)
        return True

    def _insert(self, stamp: int, pose: np.ndarray) -> bool:
        """Insert a valid sample in stamp order (duplicates, capacity); True when held."""
        i = bisect.bisect_left(self._stamps, stamp)
        if i < len(self._stamps) and self._stamps[i] == stamp:
            self._counters["duplicate"] += 1
            return False
        if len(self._stamps) >= self.capacity:
            if i == 0:
                self._counters["dropped_too_old"] += 1
                return False
            del self._stamps[0]
            del self._poses[0]
            self._counters["evicted"] += 1
            i -= 1
        if i < len(self._stamps):
            self._counters["out_of_order"] += 1
        self._stamps.insert(i, stamp)
        self._poses.insert(i, pose)
        self._counters["added"] += 1
        return True

    # --- queries -------------------------------------------------------------------------------
    def _locate(self, stamp: int) -> tuple[LookupStatus, str, int, int]:
        """``(status, how, i0, i1)``: ``how`` in {"exact", "nearest", "interpolated", ""}."""
        s = self._stamps
        if not s:
            return LookupStatus.EMPTY, "", -1, -1
        i = bisect.bisect_left(s, stamp)
        if i < len(s) and s[i] == stamp:
            return LookupStatus.OK, "exact", i, i
        tol = self.extrapolation_tol_ns
        if i == 0:
            if s[0] - stamp <= tol:
                return LookupStatus.OK, "nearest", 0, 0
            return LookupStatus.BEFORE_BUFFER, "", -1, -1
        if i == len(s):
            if stamp - s[-1] <= tol:
                return LookupStatus.OK, "nearest", i - 1, i - 1
            if stamp - s[-1] <= self.max_gap_ns:
                return LookupStatus.WAIT, "", -1, -1
            return LookupStatus.AFTER_BUFFER, "", -1, -1
        if s[i] - s[i - 1] <= self.max_gap_ns:
            return LookupStatus.OK, "interpolated", i - 1, i
        d0, d1 = stamp - s[i - 1], s[i] - stamp
        if min(d0, d1) <= tol:
            j = i - 1 if d0 <= d1 else i
            return LookupStatus.OK, "nearest", j, j
        return LookupStatus.GAP_TOO_LARGE, "", -1, -1

    def lookup_status(self, stamp_ns: int) -> LookupStatus:
        """What :meth:`lookup` would do for ``stamp_ns`` now (no counter changes).

        ``WAIT``/``EMPTY`` (``status.retry``): queue the image and ask again when newer poses
        arrived; the caller bounds the waiting time. Any other non-``OK`` status is final.
        """
        stamp = _check_int("stamp_ns", stamp_ns, 0)
        return self._locate(stamp)[0]

    def lookup(self, stamp_ns: int, *, count: bool = True) -> np.ndarray | None:
        """The pose at ``stamp_ns``, shape (4, 4), or ``None`` (counted by reason unless
        ``count`` is False: a look-ahead that is not a use of the pose).

        A ``WAIT`` stamp is counted as ``"lookup_after_buffer"`` here: call
        :meth:`lookup_status` first to decide whether to retry later.
        """
        stamp = _check_int("stamp_ns", stamp_ns, 0)
        status, how, i0, i1 = self._locate(stamp)
        if status is not LookupStatus.OK:
            key = "after_buffer" if status is LookupStatus.WAIT else status.value
            self._counters[f"lookup_{key}"] += count
            return None
        self._counters[f"lookup_{how}"] += count
        if how != "interpolated":
            return self._poses[i0].copy()
        t0, t1 = self._stamps[i0], self._stamps[i1]
        u = (stamp - t0) / (t1 - t0)
        return interpolate_se3(self._poses[i0], self._poses[i1], u)
