"""The stored pairs of one edge: preallocated arrays, their snapshots, :class:`KeptPairs`.

:class:`_EdgeStore` holds the kept pairs of one edge ``(tag, camera)`` of
:class:`~rwhec_ros.sync.accumulator.PairAccumulator` (which decides what is kept: the keyframe
test and the full-edge policy) in preallocated float64/int64 arrays of 360 bytes per slot (stamp
8, A 128, B 128, sigma 8, kappa 8, tag corners 64, nearest-neighbour bookkeeping 16), grown by
doubling up to ``max_pairs_per_edge`` slots; boards widen the corner slots (see the accumulator's
module docstring for the memory bound). Snapshots (:meth:`_EdgeStore.copy`, a
:class:`KeptPairs`) are read-only views of the arrays while the pairs only grow at their end in
stamp order, else sorted copies; ``lineage`` names such a growing sequence.

Not thread-safe: the accumulator's caller serialises access.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .edge_pairs import DatasetEdge

__all__ = ["KeptPairs"]

_BYTES_PER_SLOT = 8 + 128 + 128 + 8 + 8 + 64 + 8 + 8
_BYTES_PER_EDGE_OVERHEAD = 8192
_INITIAL_SLOTS = 64


def _rotation_angles(R_stack: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Geodesic angles between each of (n, 3, 3) and (3, 3), accurate near 0 and pi."""
    Rel = np.swapaxes(R_stack, -1, -2) @ R
    c = 0.5 * (np.trace(Rel, axis1=-2, axis2=-1) - 1.0)
    w = np.stack(
        [Rel[:, 2, 1] - Rel[:, 1, 2], Rel[:, 0, 2] - Rel[:, 2, 0], Rel[:, 1, 0] - Rel[:, 0, 1]],
        axis=-1,
    )
    s = 0.5 * np.linalg.norm(w, axis=-1)
    return np.arctan2(s, c)


def _corners(value, points=None, most: int = 0) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``(corners, points)``: four finite tag corners (4, 2) and None; or, with board points,
    ``4 <= K <= most`` finite corners (K, 2) and their points (K, 3); ``(None, None)`` when
    absent or not that."""
    if value is None:
        return None, None
    try:
        c = np.asarray(value, dtype=float)
        p = None if points is None else np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        return None, None
    if p is None:
        ok = c.shape == (4, 2) and np.isfinite(c).all()
        return (c, None) if ok else (None, None)
    ok = (c.ndim == 2 and c.shape[1] == 2 and 4 <= c.shape[0] <= most
          and p.shape == (c.shape[0], 3) and np.isfinite(c).all() and np.isfinite(p).all())
    return (c, p) if ok else (None, None)


class _EdgeStore:
    """Growing preallocated arrays of one edge plus nearest-neighbour bookkeeping."""

    _FIELDS = ("stamps", "A", "B", "sigma", "kappa", "corners", "points", "nn_dist", "nn_idx")
    _FILL = {"nn_dist": np.inf, "corners": np.nan, "points": np.nan}  # of new slots (else 0)
    _SHARED = ("stamps", "A", "B", "sigma", "kappa")  # the arrays :meth:`copy` may share

    def __init__(self, x: str, y: str, max_pairs: int) -> None:
        self.x, self.y = x, y
        self.n = 0
        self.last_A: np.ndarray | None = None
        self.max_stamp = -1  # the newest stamp stored (or replaced)
        #: Identifies the stamp-sorted sequence of kept pairs while it only grows at its end; a
        #: new object whenever a kept pair changes, goes or is inserted before the newest.
        self.lineage = object()
        #: Read-only views of the pair arrays were handed out (:meth:`copy`): the next change of
        #: a stored pair first moves the arrays (:meth:`detach`), so the views never change.
        self.shared = False
        self.in_order = True  # the slots hold the pairs in stamp order
        self._views: list[np.ndarray] | None = None  # read-only views of the _SHARED arrays
        self._snapshot: KeptPairs | None = None  # the last copy(), while nothing changed
        slots = min(_INITIAL_SLOTS, max_pairs)
        self.stamps = np.zeros(slots, dtype=np.int64)
        self.A = np.zeros((slots, 4, 4))
        self.B = np.zeros((slots, 4, 4))
        self.sigma = np.zeros(slots)
        self.kappa = np.zeros(slots)
        self.corners = np.full((slots, 4, 2), np.nan)  # detected corners [px]; NaN: none
        self.points = np.full((slots, 0, 3), np.nan)  # their board-frame points (boards only)
        self.nn_dist = np.full(slots, np.inf)  # distance of each pair to its nearest neighbour
        self.nn_idx = np.full(slots, -1, dtype=np.int64)  # index of that neighbour

    def __getstate__(self) -> dict:
        """For copies and pickles: the arrays without the views handed out (a copy's views are
        made from its own arrays)."""
        state = self.__dict__.copy()
        state.update(_views=None, _snapshot=None, shared=False)
        return state

    def grow(self, slots: int) -> None:
        """Reallocate every array to ``slots`` entries, keeping the first ``n``."""
        for name in self._FIELDS:
            old = getattr(self, name)
            new = np.full((slots,) + old.shape[1:], self._FILL.get(name, 0), dtype=old.dtype)
            new[: self.n] = old[: self.n]
            setattr(self, name, new)
        self.shared = False  # handed-out views keep the old arrays
        self._views = None

    def detach(self) -> None:
        """Before a stored pair is changed in place: give the pair arrays new memory when
        views of them were handed out (so those views keep their values), and start a new
        lineage (the sorted sequence no longer just grows)."""
        if self.shared:
            for name in self._SHARED:
                setattr(self, name, getattr(self, name).copy())
            self.shared = False
            self._views = None
        self.lineage = object()
        self._snapshot = None

    @property
    def slots(self) -> int:
        return int(self.stamps.shape[0])

    def nbytes(self) -> int:
        return sum(getattr(self, name).nbytes for name in self._FIELDS)

    def distances(self, A: np.ndarray, rot_scale: float, trans_scale: float) -> np.ndarray:
        """Keyframe distance of ``A`` to each stored ``A``, shape (n,)."""
        stored = self.A[: self.n]
        rot = _rotation_angles(stored[:, :3, :3], A[:3, :3]) / rot_scale
        trans = np.linalg.norm(stored[:, :3, 3] - A[:3, 3], axis=-1) / trans_scale
        return np.maximum(rot, trans)

    def widen(self, width: int) -> None:
        """Make room for ``width`` board corners per slot with their board-frame points; tag
        corners stored before (an edge keeps one kind) are dropped."""
        self.corners = np.full((self.slots, width, 2), np.nan)
        self.points = np.full((self.slots, width, 3), np.nan)

    def copy(self) -> KeptPairs:
        """The kept pairs sorted by stamp (no re-validation). Pairs stored in stamp order (the
        usual case: they arrive in time order) are handed out as read-only views of the first
        ``n`` slots, which never change afterwards (appends write later slots; a change of a
        stored pair first moves the arrays, :meth:`detach`); otherwise sorted copies. The same
        object again while no pair was stored since."""
        if self._snapshot is not None:
            return self._snapshot
        n = self.n
        if self.in_order:
            if self._views is None:
                self._views = [getattr(self, name).view() for name in self._SHARED]
                for v in self._views:
                    v.flags.writeable = False  # and so every slice of it
            self.shared = True
            arrays = [v[:n] for v in self._views]
        else:
            order = np.argsort(self.stamps[:n], kind="stable")
            arrays = [getattr(self, name)[:n][order] for name in self._SHARED]
            for a in arrays:
                a.flags.writeable = False
        self._snapshot = KeptPairs._of(self.x, self.y, *arrays, self.lineage)
        return self._snapshot

    def write(self, i: int, stamp: int, A, B, sigma: float, kappa: float,
              corners=None, points=None) -> None:
        """Store a pair in slot ``i``: a new one (``i == n``, then ``n`` is raised by the
        caller) or a replacement (``i < n``, :meth:`detach` first). A new pair older than the
        newest stored goes inside the sorted sequence: a new lineage."""
        if i < self.n:
            self.detach()
            self.in_order = False
        elif stamp < self.max_stamp:
            self.lineage = object()
            self.in_order = False
        self._snapshot = None
        self.max_stamp = max(self.max_stamp, int(stamp))
        self.stamps[i] = stamp
        self.corners[i] = np.nan
        self.points[i] = np.nan
        if corners is not None:
            self.corners[i, : len(corners)] = corners
        if points is not None:
            self.points[i, : len(points)] = points
        self.A[i] = A
        self.B[i] = B
        self.sigma[i] = sigma
        self.kappa[i] = kappa

    def data(self, rotation_tol: float) -> DatasetEdge:
        """The kept pairs sorted by stamp (copies), validated with ``rotation_tol``."""
        order = np.argsort(self.stamps[: self.n], kind="stable")
        corners, points = self.corners[: self.n][order], None
        if self.points.shape[1]:  # board corners: as wide as the most any pair has
            width = max(4, int(np.isfinite(corners[..., 0]).sum(axis=1).max()))
            corners, points = corners[:, :width].copy(), self.points[: self.n][order][:, :width]
        return DatasetEdge(
            x=self.x,
            y=self.y,
            stamps_ns=self.stamps[: self.n][order].copy(),
            A=self.A[: self.n][order].copy(),
            B=self.B[: self.n][order].copy(),
            sigma=self.sigma[: self.n][order].copy(),
            kappa=self.kappa[: self.n][order].copy(),
            rotation_tol=rotation_tol,
            corners_px=corners.copy(),
            corner_points_m=None if points is None else points.copy(),
        )



@dataclass(frozen=True)
class KeptPairs:
    """One edge's kept pairs, sorted by stamp (:meth:`PairAccumulator.kept_pairs`): ``stamps_ns``
    (N,), ``A``, ``B`` (N, 4, 4), ``sigma``, ``kappa`` (N,), read-only arrays that never change
    (views of the stored arrays, or copies).

    ``lineage``: an object naming the edge's sequence of kept pairs while it only grows at its
    end. Two snapshots of an edge with the same lineage (compared by identity) hold the same
    first pairs, bit for bit, up to the smaller count; a pair replaced (full edge), a pair
    arriving older than the newest, changed precisions (:meth:`PairAccumulator.set_precisions`)
    or a cleared accumulator give a new lineage. ``None``: unknown (no such promise)."""

    x: str
    y: str
    stamps_ns: np.ndarray
    A: np.ndarray
    B: np.ndarray
    sigma: np.ndarray
    kappa: np.ndarray
    lineage: object = None

    @property
    def n(self) -> int:
        return int(self.stamps_ns.shape[0])

    @classmethod
    def _of(cls, x: str, y: str, stamps_ns: np.ndarray, A: np.ndarray, B: np.ndarray,
            sigma: np.ndarray, kappa: np.ndarray, lineage: object) -> KeptPairs:
        """``KeptPairs(x, y, stamps_ns, A, B, sigma, kappa, lineage)``, its fields set at once
        (the frozen dataclass's ``__init__`` sets them one by one through
        ``object.__setattr__``, twice the time: a snapshot under the session's lock makes one
        per edge)."""
        obj = object.__new__(cls)
        obj.__dict__.update(x=x, y=y, stamps_ns=stamps_ns, A=A, B=B, sigma=sigma, kappa=kappa,
                            lineage=lineage)
        return obj


