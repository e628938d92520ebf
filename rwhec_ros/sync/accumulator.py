"""Accumulation of synchronised ``(A, B)`` measurement pairs per edge, with keyframe selection.

One edge is an (X-frame, Y-frame) = (tag, camera) pair of the problem graph (paper Section 4.5);
each offered pair satisfies ``A_i X_j = Y_k B_i`` (eq. (7)) with ``A = T_<camera carrier>_<tag
carrier>`` (noise-free, interpolated from the pose stream) and ``B = T_cam_tag`` (noisy, from
the detector).

Keyframe selection: a pair is kept only if its ``A`` moved by more than ``keyframe_rotation_rad``
(geodesic angle) OR ``keyframe_translation_m`` (``|t_A - t_A_last|``, equal to the translation of
``A_last^-1 A``) since the edge's last kept pair, so a stationary robot does not flood an edge with
copies of the same constraint. The first pair of an edge is always kept.

Memory bound: pairs are stored in preallocated float64/int64 arrays of 360 bytes per slot
(stamp 8, A 128, B 128, sigma 8, kappa 8, tag corners 64, nearest-neighbour bookkeeping 16), grown
by doubling up to ``max_pairs_per_edge`` slots, so the memory held between calls never exceeds
``max_edges * (360 * max_pairs_per_edge + 8192)`` bytes (8192 bytes cover the per-edge Python
objects, measured at 3-4.5 kB with ``tracemalloc``); with the defaults (256 edges, 2000 pairs)
that is 186.4 MB. An offer needs transient work arrays of a few hundred bytes per stored pair of
its edge. See :meth:`PairAccumulator.memory_bound_bytes` and :meth:`PairAccumulator.nbytes`.
Board corners (``board_corners`` = ``M`` > 0, the most corners of a board pair): an edge that
receives them widens its corner slots to ``M`` pixels (16 bytes each) and their board-frame
points (24 bytes each), so the bound per slot becomes ``360 + 16 (M - 4) + 24 M`` bytes (for an
AprilGrid of 6x6 tags, M = 144: 5,816 bytes, 11.6 MB per edge of 2000 pairs); tag edges keep
their 360-byte slots.

Full edge policy (counted, never silent): when an edge holds ``max_pairs_per_edge`` pairs, a new
keyframe replaces the most redundant stored pair (the one closest to its nearest stored
neighbour) if the new pair's nearest-neighbour distance, without that pair, is larger
(``"replaced_redundant"``); otherwise the new pair is dropped (``"dropped_full"``). The distance
between two pairs is ``max(angle / keyframe_rotation_rad, |t_A1 - t_A2| / keyframe_translation_m)``
on their ``A``, so the stored set keeps spreading over the visited poses.
Offers for a new edge beyond ``max_edges`` are dropped (``"dropped_max_edges"``).

Determinism promise: each edge's stored pairs are a deterministic function of the sequence of
pairs offered *to that edge*; the interleaving of offers across edges does not matter. Offering
pairs in stamp order (as the ROS layer does after synchronisation) therefore makes the result
independent of the arrival order of poses and images. Outputs are sorted by stamp.

Not thread-safe: the caller serialises access (e.g. one lock in the live session).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Collection, Sequence

import numpy as np

from ..core.problem import DEFAULT_ROTATION_TOL, Problem, check_transforms
from .board_turns import TURN, apply_turns, resolve_turns, turn_decisions
from .edge_pairs import DatasetEdge
from .edge_store import (
    _BYTES_PER_EDGE_OVERHEAD,
    _BYTES_PER_SLOT,
    KeptPairs,
    _corners,
    _EdgeStore,
)
from .problems import problem_from_edges

__all__ = ["PairAccumulator", "PairListener", "KeptPairs", "problem_from_edges"]

#: ``callback(x_name, y_name, A (4, 4), B (4, 4))``, called for every kept pair.
PairListener = Callable[[str, str, np.ndarray, np.ndarray], None]

_COUNTERS = (
    "offered",
    "kept",
    "skipped_no_motion",
    "duplicate_stamp",
    "replaced_redundant",
    "dropped_full",
    "dropped_max_edges",
    "rejected_invalid",
)


def _is_int(value: object) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)



def _pose_change(A0: np.ndarray, A1: np.ndarray) -> tuple[float, float]:
    """``(angle, shift)`` from pose ``A0`` to ``A1`` (both (4, 4), rigid): the geodesic angle of
    ``R0^T R1`` (rad, as :func:`_rotation_angles`) and ``||t1 - t0||`` (m). Plain floats: the
    keyframe test runs for every target of every image (motion gate), where numpy's per-call
    overhead on 3 x 3 matrices cost ~20x the arithmetic and held the GIL against the
    detection threads."""
    a, b = A0.tolist(), A1.tolist()
    r = [[a[0][i] * b[0][j] + a[1][i] * b[1][j] + a[2][i] * b[2][j] for j in range(3)]
         for i in range(3)]
    c = 0.5 * (r[0][0] + r[1][1] + r[2][2] - 1.0)
    s = 0.5 * math.sqrt((r[2][1] - r[1][2]) ** 2 + (r[0][2] - r[2][0]) ** 2
                        + (r[1][0] - r[0][1]) ** 2)
    shift = math.sqrt((b[0][3] - a[0][3]) ** 2 + (b[1][3] - a[1][3]) ** 2
                      + (b[2][3] - a[2][3]) ** 2)
    return math.atan2(s, c), shift



class PairAccumulator:
    """Per-edge store of synchronised measurement pairs with keyframe selection.

    Parameters
    ----------
    keyframe_rotation_rad : float
        Keep a pair when ``A`` rotated by more than this [rad] since the edge's last kept pair
        (default 2 degrees).
    keyframe_translation_m : float
        ... or translated by more than this [m] (default 1 cm).
    max_pairs_per_edge : int
        Stored pairs per edge (default 2000); see the module docstring for the full-edge policy.
    max_edges : int
        Number of edges (default 256); offers for further edges are dropped and counted.
    rotation_tol : float
        Rigid-transform validation tolerance for ``A`` and ``B`` (as :meth:`Edge.build`).
    board_corners : int
        The most corners a board pair offers (the session's largest board); 0 (default): board
        corners are not kept. Raises the memory bound (module docstring).
    turnable : collection of str
        Targets (X frames) that look the same turned by 180 degrees (symmetric chessboards):
        their pairs are stored as detected and handed out (:meth:`edges`, :meth:`kept_pairs`,
        :meth:`to_problem`) with the views whose corner order is turned turned back and the
        views whose turn cannot be told left out (:mod:`rwhec_ros.sync.board_turns`;
        :meth:`turn_report`).
    """

    def __init__(
        self,
        keyframe_rotation_rad: float = float(np.deg2rad(2.0)),
        keyframe_translation_m: float = 0.01,
        max_pairs_per_edge: int = 2000,
        max_edges: int = 256,
        *,
        rotation_tol: float = DEFAULT_ROTATION_TOL,
        board_corners: int = 0,
        turnable: Collection[str] = (),
    ) -> None:
        for name, value in (
            ("keyframe_rotation_rad", keyframe_rotation_rad),
            ("keyframe_translation_m", keyframe_translation_m),
            ("rotation_tol", rotation_tol),
        ):
            if not (isinstance(value, numbers.Real) and np.isfinite(value) and value > 0):
                raise ValueError(f"{name}: must be finite and > 0, got {value!r}")
        for name, value, minimum in (
            ("max_pairs_per_edge", max_pairs_per_edge, 2),
            ("max_edges", max_edges, 1),
        ):
            if not _is_int(value) or value < minimum:
                raise ValueError(f"{name}: expected an integer >= {minimum}, got {value!r}")
        if not _is_int(board_corners) or not (board_corners == 0 or board_corners >= 4):
            raise ValueError(f"board_corners: expected 0 or an integer >= 4, got "
                             f"{board_corners!r}")
        self.board_corners = int(board_corners)
        self.turnable = frozenset(str(t) for t in turnable)
        self.keyframe_rotation_rad = float(keyframe_rotation_rad)
        self.keyframe_translation_m = float(keyframe_translation_m)
        self.max_pairs_per_edge = int(max_pairs_per_edge)
        self.max_edges = int(max_edges)
        self.rotation_tol = float(rotation_tol)
        self._edges: dict[tuple[str, str], _EdgeStore] = {}
        self._x_frames: set[str] = set()
        self._y_frames: set[str] = set()
        self._listeners: list[PairListener] = []
        self._counters = dict.fromkeys(_COUNTERS, 0)
        self._turn_report: dict[tuple[str, str], dict] = {}
        self._turn_cache: tuple | None = None  # (state of the stored pairs, decisions)

    # --- listeners -----------------------------------------------------------------------------
    def add_listener(self, callback: PairListener) -> None:
        """Call ``callback(x, y, A, B)`` (copies) for every pair kept from now on.

        Listeners are not told when a full edge later replaces a pair. Exceptions propagate to
        the caller of :meth:`offer` (after the pair has been stored).
        """
        if not callable(callback):
            raise ValueError(f"callback: expected a callable, got {callback!r}")
        self._listeners.append(callback)

    def remove_listener(self, callback: PairListener) -> None:
        """Stop calling ``callback``; unknown callbacks raise ``ValueError``."""
        try:
            self._listeners.remove(callback)
        except ValueError:
            raise ValueError(f"callback: not a registered listener: {callback!r}") from None

    # --- input ---------------------------------------------------------------------------------
    def moved(self, A0: np.ndarray, A1: np.ndarray, fraction: float = 1.0) -> bool:
        """Whether the pose changed from ``A0`` to ``A1`` (both (4, 4), rigid) by more than
        ``fraction`` times a keyframe threshold (``keyframe_rotation_rad`` or
        ``keyframe_translation_m``; ``fraction = 1``: the motion the keyframe test asks of an
        edge between two kept pairs)."""
        angle, shift = _pose_change(np.asarray(A0, dtype=float), np.asarray(A1, dtype=float))
        return (angle > fraction * self.keyframe_rotation_rad
                or shift > fraction * self.keyframe_translation_m)

    def _moved(self, last_A: np.ndarray, A: np.ndarray) -> bool:
        angle, shift = _pose_change(last_A, A)
        return angle > self.keyframe_rotation_rad or shift > self.keyframe_translation_m

    def _distances(self, store: _EdgeStore, A: np.ndarray) -> np.ndarray:
        return store.distances(A, self.keyframe_rotation_rad, self.keyframe_translation_m)

    def _check_names(self, x: object, y: object) -> None:
        for field_name, value in (("x", x), ("y", y)):
            if not isinstance(value, str) or not value:
                raise ValueError(f"{field_name}: expected a non-empty frame name, got {value!r}")
        if x == y:
            raise ValueError(f"x and y must differ, both are {x!r}")
        if x in self._y_frames:
            raise ValueError(f"x: frame {x!r} is already used as a Y-frame")
        if y in self._x_frames:
            raise ValueError(f"y: frame {y!r} is already used as an X-frame")

    def _validate(self, x: str, y: str, stamp_ns, A, B, sigma, kappa) -> tuple:
        name = f"offer ({x}, {y})"
        if not _is_int(stamp_ns):
            raise ValueError(f"{name} stamp_ns: expected integer nanoseconds, got {stamp_ns!r}")
        if stamp_ns < 0:
            raise ValueError(f"{name} stamp_ns: must be >= 0, got {stamp_ns!r}")
        A = check_transforms(A, what=f"{name} A", rotation_tol=self.rotation_tol)
        B = check_transforms(B, what=f"{name} B", rotation_tol=self.rotation_tol)
        if A.shape[0] != 1 or B.shape[0] != 1:
            raise ValueError(f"{name}: expected one (4, 4) A and B, got {A.shape} and {B.shape}")
        for field_name, value in (("sigma", sigma), ("kappa", kappa)):
            if not (isinstance(value, numbers.Real) and np.isfinite(value) and value > 0):
                raise ValueError(f"{name} {field_name}: must be finite and > 0, got {value!r}")
        return int(stamp_ns), A[0], B[0], float(sigma), float(kappa)

    def offer(
        self,
        x: str,
        y: str,
        stamp_ns: int,
        A: np.ndarray,
        B: np.ndarray,
        sigma: float,
        kappa: float,
        *,
        strict: bool = False,
        corners_px: np.ndarray | None = None,
        corner_points_m: np.ndarray | None = None,
    ) -> bool:
        """Offer one pair of edge ``(x, y)``; returns True when it was kept.

        Parameters
        ----------
        x, y : str
            X-frame (tag) and Y-frame (camera) names. A name used as X and as Y raises
            ``ValueError`` (a configuration error, not bad data).
        stamp_ns : int
            Image stamp [ns]; a stamp already stored for this edge is dropped
            (``"duplicate_stamp"``).
        A, B : ndarray, shape (4, 4)
            ``T_<camera carrier>_<tag carrier>`` and ``T_cam_tag`` at ``stamp_ns`` (copied).
        sigma, kappa : float
            Precision of ``B``: translation standard deviation [m], Langevin concentration.
        strict : bool
            Raise ``ValueError`` for invalid stamp/A/B/sigma/kappa instead of counting
            ``"rejected_invalid"`` and returning False.
        corners_px : ndarray, shape (4, 2) or (K, 2), optional
            The detected corners [px] of ``B`` (kept with the pair for the reprojection
            error): a tag's four, or ``K`` corners of a board with ``corner_points_m``.
            Corners that are not that (not finite; a board's when ``board_corners`` is 0 or
            below ``K``) are not kept (the pair is).
        corner_points_m : ndarray, shape (K, 3), optional
            Boards: the same corners in the board frame [m].
        """
        self._check_names(x, y)
        self._counters["offered"] += 1
        try:
            stamp, A, B, sigma, kappa = self._validate(x, y, stamp_ns, A, B, sigma, kappa)
        except ValueError:
            if strict:
                raise
            self._counters["rejected_invalid"] += 1
            return False
        key = (x, y)
        store = self._edges.get(key)
        if store is None:
            if len(self._edges) >= self.max_edges:
                self._counters["dropped_max_edges"] += 1
                return False
            store = self._edges[key] = _EdgeStore(x, y, self.max_pairs_per_edge)
            self._x_frames.add(x)
            self._y_frames.add(y)
        refusal = self._refusal(store, stamp, A)
        if refusal is not None:
            self._counters[refusal] += 1
            return False
        corners = _corners(corners_px, corner_points_m, self.board_corners)
        board_edge = store.points.shape[1] > 0
        if corners[1] is not None and not board_edge:
            store.widen(max(4, self.board_corners))
        elif corners[1] is None and board_edge:  # an edge keeps one kind of corners
            corners = (None, None)
        if store.n < self.max_pairs_per_edge:
            self._append(store, stamp, A, B, sigma, kappa, corners)
        else:
            self._replace_most_redundant(store, stamp, A, B, sigma, kappa, corners)
        store.last_A = A.copy()
        self._counters["kept"] += 1
        for callback in list(self._listeners):
            callback(x, y, A.copy(), B.copy())
        return True

    def _refusal(self, store: _EdgeStore, stamp: int, A: np.ndarray) -> str | None:
        """The counter of why ``store`` would refuse a pair at ``(stamp, A)`` whatever its ``B``,
        or None when it would keep it (the keyframe rules of the module docstring)."""
        if store.n and np.any(store.stamps[: store.n] == stamp):
            return "duplicate_stamp"
        if store.last_A is not None and not self._moved(store.last_A, A):
            return "skipped_no_motion"
        if store.n >= self.max_pairs_per_edge and self._replacement(store, A) is None:
            return "dropped_full"
        return None

    def would_keep(self, x: str, y: str, stamp_ns: int, A: np.ndarray) -> bool:
        """Whether :meth:`offer` would keep a valid pair of edge ``(x, y)`` at ``(stamp_ns, A)``
        now; it changes nothing (no counter, no pair).

        The keyframe rules use the stamp and ``A`` only, never ``B``, so this answers before a
        detector has measured ``B`` (the live session skips tag detection where no edge of the
        camera would keep a pair). An edge not seen yet would keep its first pair unless
        ``max_edges`` edges exist already. ``A`` is assumed rigid (:meth:`offer` validates it).
        """
        store = self._edges.get((x, y))
        if store is None:
            return len(self._edges) < self.max_edges
        return self._refusal(store, int(stamp_ns), np.asarray(A, dtype=float)) is None

    def _replacement(self, store: _EdgeStore, A: np.ndarray) -> tuple[int, np.ndarray] | None:
        """For a full edge: ``(r, d)``, the most redundant stored pair ``r`` and the distances
        ``d`` of ``A`` to the stored pairs (``d[r] = inf``), when replacing ``r`` by ``A``
        spreads the set better; None otherwise."""
        n = store.n
        r = int(np.argmin(store.nn_dist[:n]))
        d = self._distances(store, A)
        d[r] = np.inf
        if not d.min() > store.nn_dist[r]:
            return None
        return r, d

    def _append(self, store: _EdgeStore, stamp: int, A, B, sigma: float, kappa: float,
                corners=(None, None)) -> None:
        if store.n == store.slots:
            store.grow(min(2 * store.slots, self.max_pairs_per_edge))
        d = self._distances(store, A)
        k = store.n
        store.write(k, stamp, A, B, sigma, kappa, *corners)
        if k:
            closer = d < store.nn_dist[:k]
            store.nn_dist[:k][closer] = d[closer]
            store.nn_idx[:k][closer] = k
            store.nn_dist[k] = d.min()
            store.nn_idx[k] = int(np.argmin(d))
        store.n = k + 1

    def _replace_most_redundant(
        self, store: _EdgeStore, stamp: int, A, B, sigma: float, kappa: float,
        corners=(None, None)
    ) -> None:
        """Replace the most redundant pair by the new one (``_refusal`` said it spreads)."""
        n = store.n
        r, d = self._replacement(store, A)
        store.write(r, stamp, A, B, sigma, kappa, *corners)
        others = np.arange(n) != r
        affected = np.flatnonzero(others & (store.nn_idx[:n] == r))
        closer = others & (d < store.nn_dist[:n])
        store.nn_dist[:n][closer] = d[closer]
        store.nn_idx[:n][closer] = r
        for a in affected:
            da = self._distances(store, store.A[a])
            da[a] = np.inf
            store.nn_dist[a] = da.min()
            store.nn_idx[a] = int(np.argmin(da))
        store.nn_dist[r] = d.min()
        store.nn_idx[r] = int(np.argmin(d))
        self._counters["replaced_redundant"] += 1

    # --- output --------------------------------------------------------------------------------
    def edges(self) -> dict[tuple[str, str], DatasetEdge]:
        """Kept pairs per edge ``(x, y)`` (sorted by stamp; copies), in first-offer order, as
        the records of a :class:`~rwhec_ros.data.dataset.Dataset`."""
        return self._turned({key: store.data(self.rotation_tol)
                             for key, store in self._edges.items() if store.n})

    def kept_pairs(self) -> dict[tuple[str, str], KeptPairs]:
        """Kept pairs per edge ``(x, y)`` like :meth:`edges`, but as plain arrays without the
        validation of a data-set record (every pair was validated when offered): the cheapest
        snapshot to take under a lock (the live re-solve's,
        :meth:`~rwhec_ros.session.CalibrationSession.pairs_snapshot`). Edges whose pairs lie
        in stamp order (the usual case) are read-only views of the stored arrays, taken in
        constant time, which the accumulator never changes afterwards (see
        :attr:`KeptPairs.lineage`); others sorted copies."""
        return self._turned({key: store.copy() for key, store in self._edges.items()
                             if store.n})

    def _turned(self, data: dict) -> dict:
        """``data`` with the views of the :attr:`turnable` targets turned back
        (:mod:`rwhec_ros.sync.board_turns`); edges left out whole are kept with their reason
        for :meth:`turn_report`. The turns are decided once per state of the stored pairs (each
        edge's count and lineage) and applied to :meth:`edges` and :meth:`kept_pairs` alike."""
        if not self.turnable or not any(x in self.turnable for x, _ in data):
            self._turn_report = {}
            return data
        state = tuple((key, store.n, store.lineage) for key, store in self._edges.items()
                      if store.n)
        if self._turn_cache is None or self._turn_cache[0] != state:
            decisions, self._turn_report = turn_decisions(data, self.turnable)
            self._turn_cache = (state, decisions)
        return apply_turns(data, self._turn_cache[1])

    def tracker_B(self, x: str, y: str, stamp_ns: int, B: np.ndarray) -> np.ndarray | None:
        """``B`` of the kept pair ``(x, y, stamp_ns)`` for an incremental consumer (the live
        identifiability tracker): as offered for a target that is not :attr:`turnable`; else
        turned to the labelling of the edge's first stored pair, or None while its turn cannot
        be told (:func:`~rwhec_ros.sync.board_turns.resolve_turns`)."""
        store = self._edges.get((x, y))
        if x not in self.turnable or store is None or store.n < 2:
            return B
        n = store.n
        i = np.flatnonzero(store.stamps[:n] == stamp_ns)
        if not len(i):
            return None
        res = resolve_turns(store.A[:n], store.B[:n], views=np.array([0, i[0]]))
        if not res.resolved.all():
            return None
        return B @ TURN if res.turned[0] != res.turned[1] else B

    def turn_report(self) -> dict[tuple[str, str], dict]:
        """Per edge of a turnable target, as of the last :meth:`edges` / :meth:`kept_pairs`:
        ``{"pairs", "turned", "unresolved"}`` and ``"left_out"`` (the reason) where the whole
        edge was left out (:func:`~rwhec_ros.sync.board_turns.resolve_edges`)."""
        return {k: dict(v) for k, v in self._turn_report.items()}

    def counts(self) -> dict[tuple[str, str], int]:
        """Number of kept pairs per edge ``(x, y)``."""
        return {key: store.n for key, store in self._edges.items() if store.n}

    def counters(self) -> dict[str, int]:
        """A copy of the event counters (fixed keys, all present from the start)."""
        return dict(self._counters)

    def nbytes(self) -> int:
        """Bytes currently allocated for stored pairs (arrays only)."""
        return sum(store.nbytes() for store in self._edges.values())

    def memory_bound_bytes(self) -> int:
        """Bound on the memory held, ``max_edges * (360 * max_pairs_per_edge + 8192)`` bytes;
        with ``board_corners`` M > 0, ``360 + 16 (M - 4) + 24 M`` bytes per slot instead."""
        slot = _BYTES_PER_SLOT
        if self.board_corners:
            slot += 16 * (self.board_corners - 4) + 24 * self.board_corners
        return self.max_edges * (slot * self.max_pairs_per_edge + _BYTES_PER_EDGE_OVERHEAD)

    def set_precisions(self, sigma: float, kappa: float) -> int:
        """Give every kept pair the precisions ``sigma`` [m] and ``kappa`` (paper eq. (14),
        (16)), e.g. after the stated noise changed; returns the number of pairs changed.
        Keyframe bookkeeping does not depend on them."""
        for field_name, value in (("sigma", sigma), ("kappa", kappa)):
            if not (isinstance(value, numbers.Real) and np.isfinite(value) and value > 0):
                raise ValueError(f"{field_name}: must be finite and > 0, got {value!r}")
        n = 0
        for store in self._edges.values():
            store.detach()
            store.sigma[: store.n] = float(sigma)
            store.kappa[: store.n] = float(kappa)
            n += store.n
        return n

    def clear(self) -> None:
        """Forget every pair and edge (counters and listeners are kept)."""
        self._edges.clear()
        self._x_frames.clear()
        self._y_frames.clear()

    def to_problem(
        self,
        x_names: Sequence[str] | None = None,
        y_names: Sequence[str] | None = None,
        unknown_scale: bool = False,
        min_pairs: int = 3,
    ) -> tuple[Problem, dict[tuple[str, str], str]]:
        """The kept pairs as a :class:`Problem` and the edges left out, with a reason each.

        Parameters
        ----------
        x_names, y_names : sequence of str, optional
            Frame order of the problem (default: sorted names of the edges). Edges of frames not
            listed are excluded. Frames left without an edge are dropped.
        unknown_scale : bool
            Monocular problem with unknown scale (paper Problem 3).
        min_pairs : int
            Edges with fewer kept pairs are excluded.

        Returns
        -------
        problem : Problem
            Edges ordered by (X index, Y index); pairs by stamp; built with :meth:`Edge.build`.
        excluded : dict[(x, y), str]
            Reason for each edge left out.

        Raises
        ------
        ValueError
            If no edge is left.
        """
        problem, excluded = problem_from_edges(self.edges(), x_names, y_names, unknown_scale,
                                               min_pairs, self.rotation_tol)
        excluded.update({key: r["left_out"] for key, r in self._turn_report.items()
                         if "left_out" in r})
        return problem, excluded
