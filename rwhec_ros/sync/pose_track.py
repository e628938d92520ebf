"""The pose stream around every kept pair: what re-interpolating a pair at a shifted stamp needs.

The pose buffer (:mod:`rwhec_ros.sync.buffer`) holds the newest few thousand samples only; a pair
kept minutes ago can no longer be looked up at another stamp. Estimating a camera's time offset
(``t_pose = t_image + delta``, :mod:`rwhec_ros.session.time_offsets`) and applying it needs the
stream at ``s + delta`` for every kept pair's stamp ``s`` and every ``|delta|`` up to the search
range, and its rate (twist) there. :class:`PoseTrack` records exactly that: every sample of the
stream within ``window_ns`` of a marked stamp (the stamps of the kept pairs), whichever arrives
first, the sample or the mark. :class:`PoseTrackData` is an immutable snapshot that interpolates
(:func:`~rwhec_ros.sync.interpolation.interpolate_se3`, as the buffer does) and differentiates.

Window: ``range + max(half_step, 50 ms) + max_gap`` on each side of a stamp, so that
``s + delta +- half_step`` (the central difference of the rate) and ``s +- 50 ms`` (whether the
pair moved) are bracketed by two samples at most ``max_gap`` apart whenever the stream has them.
Memory: 136 bytes per sample held (a 4x4 float64 pose and an int64 stamp); the windows of the
kept pairs overlap while the rig moves (pairs every few tens of milliseconds), so at most the
stream itself is held: 100 Hz for 10 minutes is 60,000 samples, 8.2 MB. ``max_samples`` bounds
it (default 200,000 samples, 27 MB); beyond, new windows are not recorded (counted ``full``) and
their pairs have no rate (they say nothing about an offset).

Not thread-safe: the caller serialises access (the live session's lock). A snapshot
(:meth:`PoseTrack.data`) never changes afterwards: samples appended later go to slots beyond it,
an insertion before its end (a late sample) first moves the arrays.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np

from ..core.lie import invert_transform
from .interpolation import se3_exp, se3_log

__all__ = ["PoseTrack", "PoseTrackData", "track_window_ns", "RATE_HALF_STEP_NS"]

_NS = 1_000_000_000
#: Half the time step [ns] of the central difference that gives the stream's rate at a stamp
#: (60 ms baseline: six samples of a 100 Hz stream apart; exact for constant-twist motion,
#: ``O(h^2)`` otherwise, a gain of ``sin(w h) / (w h)`` = 0.95 at 3 Hz). The rate is the
#: offsets' Jacobian (:mod:`rwhec_ros.core.analysis.time_offset`): its noise does not move the
#: root of their estimating equation but inflates their error and deflates their std (errors in
#: variables). With 0.5 mm / 0.5 mrad per sample at 100 Hz (``test/test_time_offsets.py``'s
#: scene, 16 seeds, 0.3 m/s): a 20 ms baseline gave offsets 0.83 ms off (RMS) with a std 1.15x
#: too small; 40, 60, 80 and 100 ms gave 0.75, 0.72, 0.73 and 0.74 ms with error / std 1.02,
#: 0.98, 0.98 and 0.99 (the piecewise-linear stream's own slope, a baseline of 0: 1.82 ms, 2.9x).
RATE_HALF_STEP_NS = 30_000_000


#: Half-width [ns] of the window over which a pair's motion is measured (whether it moved).
MOTION_HALF_WINDOW_NS = 50_000_000


def track_window_ns(range_s: float) -> int:
    """The half-width [ns] of the stream recorded around a kept pair's stamp for offsets within
    +- ``range_s``: the shifted stamp, its rate's central difference and the motion window
    around it (the pose buffer's ``max_gap`` is added by :class:`PoseTrack` itself)."""
    return int(round(float(range_s) * _NS)) + max(RATE_HALF_STEP_NS, MOTION_HALF_WINDOW_NS)


@dataclass(frozen=True, eq=False)
class PoseTrackData:
    """Samples ``poses[i]`` (``A = T_<camera carrier>_<tag carrier>``) at ``stamps_ns[i]``
    (ascending, distinct), read-only; lookups interpolate between two samples at most
    ``max_gap_ns`` apart (as :meth:`PoseBuffer.lookup <rwhec_ros.sync.buffer.PoseBuffer.lookup>`
    does, without its nearest-sample tolerance: a shifted stamp is served by interpolation or
    not at all)."""

    stamps_ns: np.ndarray
    poses: np.ndarray
    max_gap_ns: int

    def __post_init__(self) -> None:
        st = np.asarray(self.stamps_ns)
        P = np.asarray(self.poses, dtype=float)
        if st.ndim != 1 or st.dtype.kind not in "iu":
            raise ValueError(f"pose_stream stamps_ns: expected integer nanoseconds of shape (n,), "
                             f"got dtype {st.dtype} shape {st.shape}")
        if P.shape != (st.shape[0], 4, 4):
            raise ValueError(f"pose_stream poses: expected shape ({st.shape[0]}, 4, 4), got "
                             f"{P.shape}")
        if st.shape[0] > 1 and not (np.diff(st) > 0).all():
            i = int(np.argmin(np.diff(st) > 0))
            raise ValueError(f"pose_stream stamps_ns[{i + 1}]: must be after stamps_ns[{i}], "
                             f"got {int(st[i + 1])} after {int(st[i])}")
        if not np.isfinite(P).all():
            raise ValueError("pose_stream poses: non-finite value")
        if isinstance(self.max_gap_ns, bool) or int(self.max_gap_ns) < 1:
            raise ValueError(f"pose_stream max_gap_ns: must be an integer >= 1, got "
                             f"{self.max_gap_ns!r}")
        object.__setattr__(self, "stamps_ns", st.astype(np.int64, copy=False))
        object.__setattr__(self, "poses", P)
        object.__setattr__(self, "max_gap_ns", int(self.max_gap_ns))

    @property
    def n(self) -> int:
        return int(self.stamps_ns.shape[0])

    def lookup(self, stamps_ns) -> tuple[np.ndarray, np.ndarray]:
        """``(A (K, 4, 4), ok (K,))``: the stream at each stamp (interpolated on SE(3) between
        the samples around it, or the sample at exactly that stamp); ``ok`` False (and ``A`` the
        identity) where no two samples at most ``max_gap_ns`` apart bracket it."""
        q = np.atleast_1d(np.asarray(stamps_ns)).astype(np.int64)
        A = np.broadcast_to(np.eye(4), q.shape + (4, 4)).copy()
        ok = np.zeros(q.shape, dtype=bool)
        st = self.stamps_ns
        if st.shape[0] == 0:
            return A, ok
        i = np.searchsorted(st, q, side="left")
        exact = (i < st.shape[0]) & (st[np.minimum(i, st.shape[0] - 1)] == q)
        A[exact] = self.poses[i[exact]]
        ok[exact] = True
        inner = ~exact & (i > 0) & (i < st.shape[0])
        i1 = i[inner]
        t0, t1 = st[i1 - 1], st[i1]
        fine = (t1 - t0) <= self.max_gap_ns
        sel = np.flatnonzero(inner)[fine]
        if sel.size:
            i1 = i1[fine]
            P0, P1 = self.poses[i1 - 1], self.poses[i1]
            u = (q[sel] - st[i1 - 1]) / (st[i1] - st[i1 - 1])
            xi = se3_log(P1 @ invert_transform(P0))
            A[sel] = se3_exp(u[:, None] * xi) @ P0
            ok[sel] = True
        return A, ok

    def rates(self, stamps_ns, half_step_ns: int = RATE_HALF_STEP_NS
              ) -> tuple[np.ndarray, np.ndarray]:
        """``(xi (K, 6), ok (K,))``: the stream's twist rate ``[rho, omega]`` [m/s, rad/s] at
        each stamp, ``dA/dt = xi^ A`` (``A``'s parent frame), by the central difference
        ``log(A(s + h) A(s - h)^-1) / (2 h)``; NaN where either end cannot be looked up."""
        q = np.atleast_1d(np.asarray(stamps_ns)).astype(np.int64)
        h = int(half_step_ns)
        A, both = self.lookup(np.concatenate([q + h, q - h]))  # one batch: one log, one exp
        Ap, Am = A[: q.shape[0]], A[q.shape[0]:]
        ok = both[: q.shape[0]] & both[q.shape[0]:]
        xi = np.full(q.shape + (6,), np.nan)
        if ok.any():
            xi[ok] = se3_log(Ap[ok] @ invert_transform(Am[ok])) * (_NS / (2.0 * h))
        return xi, ok

    def motion(self, stamps_ns, half_window_ns: int) -> tuple[np.ndarray, np.ndarray]:
        """``(shift_m (K,), angle_rad (K,))``: how far the stream moved from ``s - w`` to
        ``s + w`` (``|t1 - t0|`` and the geodesic angle between the rotations, as the keyframe
        test measures a change of ``A``); NaN where either end cannot be looked up."""
        q = np.atleast_1d(np.asarray(stamps_ns)).astype(np.int64)
        w = int(half_window_ns)
        A, both = self.lookup(np.concatenate([q + w, q - w]))
        Ap, Am = A[: q.shape[0]], A[q.shape[0]:]
        okp, okm = both[: q.shape[0]], both[q.shape[0]:]
        shift = np.linalg.norm(Ap[:, :3, 3] - Am[:, :3, 3], axis=-1)
        rel = np.swapaxes(Am[:, :3, :3], 1, 2) @ Ap[:, :3, :3]
        c = np.clip(0.5 * (np.trace(rel, axis1=1, axis2=2) - 1.0), -1.0, 1.0)
        angle = np.arccos(c)
        bad = ~(okp & okm)
        shift[bad] = np.nan
        angle[bad] = np.nan
        return shift, angle


class PoseTrack:
    """Records the pose stream within ``window_ns`` of every marked stamp (module docstring).

    Parameters
    ----------
    window_ns : int
        Half-width [ns] of the window kept around a marked stamp (:func:`track_window_ns`);
        ``max_gap_ns`` is added, so that the samples bracketing its ends are kept too.
    max_gap_ns : int
        The lookups' largest interpolated gap (``sync.max_gap_s``).
    recent : int
        Newest samples held to fill the past part of a window when a stamp is marked (the pose
        buffer's capacity: a pair is kept within that many samples of its stamp).
    max_samples : int
        Most samples recorded (module docstring).
    """

    def __init__(self, window_ns: int, max_gap_ns: int, *, recent: int = 4000,
                 max_samples: int = 200_000) -> None:
        for name, value, low in (("window_ns", window_ns, 0), ("max_gap_ns", max_gap_ns, 1),
                                 ("recent", recent, 2), ("max_samples", max_samples, 2)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise ValueError(f"{name}: expected an integer >= {low}, got {value!r}")
        self.max_gap_ns = int(max_gap_ns)
        self.window_ns = int(window_ns) + self.max_gap_ns
        self.recent = int(recent)
        self.max_samples = int(max_samples)
        self._recent_stamps: list[int] = []
        self._recent_poses: list[np.ndarray] = []
        self._marks: list[int] = []
        self._stamps = np.zeros(256, dtype=np.int64)
        self._poses = np.zeros((256, 4, 4))
        self._n = 0
        self._shared = False  # views of the first _n slots were handed out
        self._snapshot: PoseTrackData | None = None
        self.counters = {"samples": 0, "marks": 0, "full": 0}

    def __len__(self) -> int:
        return self._n

    def nbytes(self) -> int:
        """Bytes of the recorded samples' arrays."""
        return int(self._stamps.nbytes + self._poses.nbytes)

    # --- input ---------------------------------------------------------------------------------
    def add(self, stamp_ns: int, A: np.ndarray) -> None:
        """One sample of the stream (already validated by the pose buffer): held among the
        recent ones and recorded when it lies in a marked window."""
        stamp = int(stamp_ns)
        i = bisect.bisect_left(self._recent_stamps, stamp)
        if i < len(self._recent_stamps) and self._recent_stamps[i] == stamp:
            return
        self._recent_stamps.insert(i, stamp)
        self._recent_poses.insert(i, A)
        if len(self._recent_stamps) > self.recent:
            del self._recent_stamps[0]
            del self._recent_poses[0]
        j = bisect.bisect_left(self._marks, stamp - self.window_ns)
        if j < len(self._marks) and self._marks[j] <= stamp + self.window_ns:
            self._record(stamp, A)

    def mark(self, stamp_ns: int) -> None:
        """A pair was kept at ``stamp_ns`` (the pose stream's time): record the window around it
        from the recent samples, and the samples arriving later within it."""
        stamp = int(stamp_ns)
        i = bisect.bisect_left(self._marks, stamp)
        if i < len(self._marks) and self._marks[i] == stamp:
            return
        self._marks.insert(i, stamp)
        self.counters["marks"] += 1
        lo = bisect.bisect_left(self._recent_stamps, stamp - self.window_ns)
        hi = bisect.bisect_right(self._recent_stamps, stamp + self.window_ns)
        for k in range(lo, hi):
            self._record(self._recent_stamps[k], self._recent_poses[k])

    def _record(self, stamp: int, A: np.ndarray) -> None:
        n = self._n
        if n and self._stamps[n - 1] >= stamp:
            i = int(np.searchsorted(self._stamps[:n], stamp))
            if self._stamps[i] == stamp:
                return  # recorded already
        else:
            i = n
        if n >= self.max_samples:
            self.counters["full"] += 1
            return
        if n == self._stamps.shape[0]:
            size = min(2 * n, self.max_samples)
            self._stamps = np.concatenate([self._stamps, np.zeros(size - n, dtype=np.int64)])
            self._poses = np.concatenate([self._poses, np.zeros((size - n, 4, 4))])
            self._shared = False  # handed-out views keep the old arrays
        if i < n:
            if self._shared:  # views of [0, n) were handed out: move before changing them
                self._stamps, self._poses = self._stamps.copy(), self._poses.copy()
                self._shared = False
            self._stamps[i + 1: n + 1] = self._stamps[i:n]
            self._poses[i + 1: n + 1] = self._poses[i:n]
        self._stamps[i] = stamp
        self._poses[i] = A
        self._n = n + 1
        self._snapshot = None
        self.counters["samples"] += 1

    # --- output --------------------------------------------------------------------------------
    def data(self) -> PoseTrackData:
        """The recorded samples as an immutable :class:`PoseTrackData` (read-only views that
        never change afterwards; the same object while nothing was recorded since)."""
        if self._snapshot is None:
            st = self._stamps[: self._n].view()
            P = self._poses[: self._n].view()
            st.flags.writeable = False
            P.flags.writeable = False
            self._shared = True
            self._snapshot = PoseTrackData(st, P, self.max_gap_ns)
        return self._snapshot
