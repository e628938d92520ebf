"""Boards that look the same turned by 180 degrees: which views' corner order is turned.

A chessboard with both square counts even or both odd (e.g. the ROS ``camera_calibration``
tutorial's 8 x 6 inner corners, 9 x 7 squares), or a plain symmetric circle grid (OpenCV's
``circles`` pattern, no origin circle), maps onto itself turned by 180 degrees about its normal:
nothing in one image tells its point ``k`` from point ``N - 1 - k``. The detector
labels such a board in a fixed way per image (:mod:`rwhec_ros.vision.grid_detection`), so a
view's pose ``B = T_cam_board`` may be the board's or the board turned, ``B F`` with
``F = T_board_turned`` the 180-degree turn about the board's ``z`` axis through its centre (the
board frame's origin, :mod:`rwhec_ros.vision.grids`). Which one is told by the pose stream:

**Within an edge** (one camera, one board). Two pairs ``i, l`` of the edge satisfy
``A_i X = Y B_i`` and ``A_l X = Y B_l``, so ``C = A_i^-1 A_l`` and ``D = B_i^-1 B_l`` are
conjugate (``C X = X D``) and turn by the same angle. With one of the two views turned the
measured ``D`` is ``B_i^-1 B_l F`` up to conjugation instead, whose angle is at least
``180 deg - angle(D)``. So for each two pairs whose relative turn ``angle(C)`` is below about
70 degrees one of the two labellings fits the pose stream and the other is off by tens of
degrees: the pair of pairs is *decisive* (:data:`MATCH_DEG`, :data:`GAP_DEG`). The edge's views
are then given a turn each (two-colouring of the decisive relations: a spectral start and local
flips, on up to :data:`ANCHORS` anchor views spread over the edge; every view then by the votes
of the anchors), up to one turn of the whole edge, which is chosen so that most views keep the
detector's labelling (the board frame of a symmetric board is defined only up to that turn).
A view whose anchors' votes do not agree (no decisive anchor, or more than a fifth of them
against) is left out, counted, never guessed.

**Across edges** (a board seen by several cameras): each edge's labelling is fixed only up to one
turn, and two cameras' labellings of the same board must agree. Every combination of the turns
of the board's other edges (against the edge with the most pairs) is scored by a local solve
of all edges (``mode: local`` from the closed-form start) and the sum of the pairs' rotation
misfits, each capped at :data:`MISFIT_CAP_DEG` (a stray pair weighs no more than one of a
turned edge): the consistent combination fits, a turned edge misfits by up to 180 degrees per
pair. The best is taken when every other combination misfits by at least
:data:`CROSS_EDGE_MARGIN` times the cap times the smallest such edge's pairs more; otherwise
the board's other edges are left out with the reason.

The turned views get ``B F`` and, for the corner-level steps, their corners' board-frame points
turned (``(x, y, z) -> (-x, -y, z)``): the same detections, labelled the other way.
"""

from __future__ import annotations

import itertools
from collections.abc import Collection, Mapping
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["TURN", "TurnResolution", "resolve_turns", "turn_pairs", "turn_decisions",
           "apply_turns", "resolve_edges", "turn_document", "turn_lines",
           "MATCH_DEG", "GAP_DEG", "ANCHORS", "MISFIT_CAP_DEG", "CROSS_EDGE_MARGIN"]

#: ``F = T_board_turned``: the 180-degree turn about the board's z axis through its centre.
TURN = np.diag([-1.0, -1.0, 1.0, 1.0])
#: A labelling fits two views when their relative turn matches the pose stream's within this.
MATCH_DEG = 15.0
#: ... and the other labelling misses it by at least this much more.
GAP_DEG = 30.0
#: Views compared with every view of an edge (spread over the edge in stamp order).
ANCHORS = 64
#: Across edges: a pair's rotation misfit counts at most this much [deg].
MISFIT_CAP_DEG = 30.0
#: ... and every other combination of turns must misfit by at least this many capped pairs
#: more than the best one (per pair of the smallest edge whose turn is chosen: a fraction).
CROSS_EDGE_MARGIN = 0.5
#: Combinations tried across edges at most (2^6); beyond, one edge's turn at a time.
_MAX_COMBINATIONS = 64


@dataclass(frozen=True)
class TurnResolution:
    """Which views of one edge are turned. ``turned`` (N,) bool: the view's labelling is to be
    turned (``B F``); ``resolved`` (N,) bool: False where the view's turn could not be told
    (left out)."""

    turned: np.ndarray
    resolved: np.ndarray

    @property
    def n_turned(self) -> int:
        return int(np.count_nonzero(self.turned & self.resolved))

    @property
    def n_unresolved(self) -> int:
        return int(np.count_nonzero(~self.resolved))


def _angles_deg(R1: np.ndarray, R2: np.ndarray) -> np.ndarray:
    """Angle [deg] of ``R1[a]^T R2[b]`` for all ``a, b``: (len(R1), len(R2))."""
    tr = np.einsum("akl,bkl->ab", R1, R2)
    return np.degrees(np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0)))


def _relations(A: np.ndarray, B: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """+1 (same labelling), -1 (one of the two turned) or 0 (not decisive) for views ``rows`` x
    ``cols`` (module docstring)."""
    RA, RB = A[:, :3, :3], B[:, :3, :3]
    c = _angles_deg(RA[rows], RA[cols])
    d_same = _angles_deg(RB[rows], RB[cols])
    d_turned = _angles_deg(RB[rows], RB[cols] @ TURN[:3, :3])
    e_same, e_turned = np.abs(c - d_same), np.abs(c - d_turned)
    rel = np.zeros(c.shape, dtype=np.int8)
    rel[(e_same < MATCH_DEG) & (e_turned > e_same + GAP_DEG)] = 1
    rel[(e_turned < MATCH_DEG) & (e_same > e_turned + GAP_DEG)] = -1
    return rel


def _two_colouring(rel: np.ndarray) -> np.ndarray:
    """Signs (m,) in {+1, -1} that agree with most of the symmetric relations ``rel`` (m, m):
    the leading eigenvector's signs, then single flips while they gain."""
    m = rel.shape[0]
    W = rel.astype(float)
    np.fill_diagonal(W, 0.0)
    if m == 1 or not W.any():
        return np.ones(m)
    _, V = np.linalg.eigh(W)
    s = np.where(V[:, -1] >= 0, 1.0, -1.0)
    for _ in range(m):
        gain = -2.0 * s * (W @ s)  # change of s^T W s / 2 when flipping one sign
        k = int(np.argmax(gain))
        if gain[k] <= 0:
            break
        s[k] = -s[k]
    return s


def resolve_turns(A: np.ndarray, B: np.ndarray,
                  views: np.ndarray | None = None) -> TurnResolution:
    """The turns of one edge's views (module docstring, "within an edge").

    Parameters
    ----------
    A, B : ndarray (N, 4, 4)
        The edge's pairs, ``A_i X = Y B_i``, ``B = T_cam_board`` as the detector labelled it.
    views : ndarray of int, optional
        Only these views (the result's entries in this order): the anchors decide as for all,
        at O(len(views)) instead of O(N); the turn of the whole edge is then not chosen (only
        the views' turns relative to each other are meaningful).
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    n = A.shape[0]
    rows = np.arange(n) if views is None else np.asarray(views, dtype=int)
    if n <= 1:
        return TurnResolution(np.zeros(len(rows), dtype=bool), np.ones(len(rows), dtype=bool))
    anchors = np.unique(np.linspace(0, n - 1, min(n, ANCHORS)).round().astype(int))
    ra = _relations(A, B, anchors, anchors).astype(float)
    np.fill_diagonal(ra, 0.0)  # a view is no witness of itself
    s_anchor = _two_colouring(ra)
    # anchors whose own turn is sure: their decisive relations with the others agree
    votes = ra * s_anchor[None, :] * s_anchor[:, None]
    agree, against = (votes > 0).sum(axis=1), (votes < 0).sum(axis=1)
    sure = (agree >= 1) & (against <= 0.2 * agree)
    rel = _relations(A, B, rows, anchors[sure]).astype(float)  # (rows, sure anchors)
    rel[rows[:, None] == anchors[sure][None, :]] = 0.0
    signed = rel * s_anchor[sure][None, :]
    plus, minus = (signed > 0).sum(axis=1), (signed < 0).sum(axis=1)
    s = np.where(plus >= minus, 1.0, -1.0)
    agree, against = np.maximum(plus, minus), np.minimum(plus, minus)
    resolved = (agree >= 1) & (against <= 0.2 * agree)
    turned = s < 0
    if views is None and np.count_nonzero(turned & resolved) > np.count_nonzero(
            ~turned & resolved):
        turned = ~turned  # most views keep the detector's labelling
    return TurnResolution(turned, resolved)


def turn_pairs(edge, resolution: TurnResolution):
    """``edge`` (a :class:`~rwhec_ros.sync.edge_pairs.DatasetEdge` or
    :class:`~rwhec_ros.sync.edge_store.KeptPairs`) with its turned views turned (``B F``, the
    corners' board points ``(-x, -y, z)``) and its unresolved views left out."""
    turned, keep = resolution.turned, resolution.resolved
    B = np.array(edge.B, dtype=float)
    B[turned] = B[turned] @ TURN
    fields = dict(stamps_ns=np.asarray(edge.stamps_ns)[keep], A=np.asarray(edge.A)[keep],
                  B=B[keep], sigma=np.asarray(edge.sigma)[keep],
                  kappa=np.asarray(edge.kappa)[keep])
    points = getattr(edge, "corner_points_m", None)
    if points is not None:
        points = np.array(points, dtype=float)
        points[turned, :, :2] *= -1.0
        fields.update(corners_px=np.asarray(edge.corners_px)[keep], corner_points_m=points[keep])
    elif getattr(edge, "corners_px", None) is not None:
        fields.update(corners_px=np.asarray(edge.corners_px)[keep])
    if hasattr(edge, "lineage"):
        fields["lineage"] = None  # the turns may change as pairs arrive: no promise
    return replace(edge, **fields)


def _misfit(edges: list, unknown_scale: bool) -> float:
    """Sum over the pairs of ``edges`` of their rotation misfit [deg], each capped at
    :data:`MISFIT_CAP_DEG`, after a local solve of all of them (``mode: local`` from the
    closed-form start): capped, so that a stray pair (a wrong detection) weighs no more than
    one pair of a turned edge."""
    from ..core.solve import SolveOptions, solve
    from .problems import problem_from_edges

    problem, _ = problem_from_edges({(e.x, e.y): e for e in edges},
                                    unknown_scale=unknown_scale, min_pairs=1)
    result = solve(problem, SolveOptions(mode="local"))
    X = dict(zip(result.x_names, result.X, strict=True))
    Y = dict(zip(result.y_names, result.Y, strict=True))
    total = 0.0
    for e in edges:
        left = np.asarray(e.A)[:, :3, :3] @ X[e.x][:3, :3]
        right = Y[e.y][:3, :3] @ np.asarray(e.B)[:, :3, :3]
        tr = np.einsum("nkl,nkl->n", left, right)
        angles = np.degrees(np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0)))
        total += float(np.minimum(angles, MISFIT_CAP_DEG).sum())
    return total


def turn_decisions(edges: Mapping[tuple[str, str], object], turnable: Collection[str], *,
                   unknown_scale: bool = False, min_pairs: int = 3
                   ) -> tuple[dict[tuple[str, str], TurnResolution | None],
                              dict[tuple[str, str], dict]]:
    """Per edge of a turnable board (``turnable``: target names) of ``edges`` (per ``(x, y)``)
    its views' turns (module docstring; the across-edges choice folded in), or None where the
    whole edge is left out; and per such edge what was done: ``{"pairs", "turned",
    "unresolved", "left_out"}`` (``left_out``: the reason the whole edge was left out, else
    absent). :func:`apply_turns` applies them."""
    decisions: dict[tuple[str, str], TurnResolution | None] = {}
    report: dict[tuple[str, str], dict] = {}
    by_target: dict[str, list[tuple[str, str]]] = {}
    resolved = {}
    for key, e in edges.items():
        if key[0] not in turnable:
            continue
        res = decisions[key] = resolve_turns(e.A, e.B)
        report[key] = {"pairs": int(e.n), "turned": res.n_turned,
                       "unresolved": res.n_unresolved}
        if not res.resolved.any():  # nothing left of the edge: left out whole, with the reason
            decisions[key] = None
            report[key]["left_out"] = (
                f"the turn of none of its {e.n} views of the symmetric board {key[0]!r} could "
                f"be told (no two views less than about 70 deg apart)")
            continue
        resolved[key] = turn_pairs(e, res)
        if resolved[key].n >= min_pairs:
            by_target.setdefault(key[0], []).append(key)
    shared = {k: sorted(v, key=lambda key: -resolved[key].n) for k, v in by_target.items()
              if len(v) > 1}
    if not shared:
        return decisions, report
    free = [key for keys in shared.values() for key in keys[1:]]
    others = [resolved.get(key, e) for key, e in edges.items()
              if key not in free and decisions.get(key, True) is not None
              and resolved.get(key, e).n >= min_pairs]

    def cost(flips) -> float:
        trial = [turn_pairs(resolved[key], TurnResolution(np.full(resolved[key].n, f),
                                                          np.ones(resolved[key].n, dtype=bool)))
                 for key, f in zip(free, flips, strict=True)]
        try:
            return _misfit(others + trial, unknown_scale)
        except Exception:  # noqa: BLE001 - the live path never raises: not told, edge left out
            return float("nan")

    if 2 ** len(free) <= _MAX_COMBINATIONS:
        combos = list(itertools.product((False, True), repeat=len(free)))
    else:  # one edge at a time from no turn
        best = (False,) * len(free)
        best_cost = cost(best)
        for i in range(len(free)):
            flipped = tuple(b ^ (j == i) for j, b in enumerate(best))
            c = cost(flipped)
            if c < best_cost:
                best, best_cost = flipped, c
        combos = [best] + [tuple(b ^ (j == i) for j, b in enumerate(best))
                           for i in range(len(free))]
    costs = np.array([cost(c) for c in combos])
    order = np.argsort(costs)
    best = combos[int(order[0])]
    margin = CROSS_EDGE_MARGIN * MISFIT_CAP_DEG * min(resolved[key].n for key in free)
    decisive = bool(np.isfinite(costs).all()) and (
        len(costs) == 1 or costs[order[1]] >= costs[order[0]] + margin)
    for key, flip in zip(free, best, strict=True):
        res = decisions[key]
        if not decisive:
            report[key]["left_out"] = (
                f"the turn of the symmetric board {key[0]!r} seen by {key[1]!r} could not be "
                f"matched with its other cameras' views (a solve with either turn fits "
                f"about as well)")
            decisions[key] = None
        elif flip:
            decisions[key] = TurnResolution(~res.turned, res.resolved)
            report[key]["turned"] = decisions[key].n_turned
    return decisions, report


def apply_turns(edges: Mapping[tuple[str, str], object],
                decisions: Mapping[tuple[str, str], TurnResolution | None]) -> dict:
    """``edges`` with :func:`turn_decisions`' turns applied (:func:`turn_pairs`); an edge whose
    decision is None is left out; edges without a decision as given."""
    out = {}
    for key, e in edges.items():
        if key not in decisions:
            out[key] = e
        elif decisions[key] is not None:
            out[key] = turn_pairs(e, decisions[key])
    return out


def resolve_edges(edges: Mapping[tuple[str, str], object], turnable: Collection[str], *,
                  unknown_scale: bool = False, min_pairs: int = 3
                  ) -> tuple[dict, dict[tuple[str, str], dict]]:
    """``edges`` with the views of the turnable boards turned and their unresolved views left
    out (:func:`turn_decisions`, :func:`apply_turns`), and the report of
    :func:`turn_decisions` (an edge with ``left_out`` is not in the edges returned)."""
    decisions, report = turn_decisions(edges, turnable, unknown_scale=unknown_scale,
                                       min_pairs=min_pairs)
    return apply_turns(edges, decisions), report


def turn_document(report: Mapping[tuple[str, str], dict]) -> dict[str, dict]:
    """:func:`resolve_edges`' report as the result file's ``board_turns`` mapping, keyed
    ``"(x, y)"`` like ``excluded_edges``."""
    return {f"({x}, {y})": {k: (int(v) if k != "left_out" else str(v)) for k, v in r.items()}
            for (x, y), r in report.items()}


def turn_lines(report: Mapping[tuple[str, str], dict]) -> list[str]:
    """One summary line per turn-symmetric board: per camera the views turned back of those
    kept, the views left out because their turn could not be told, an edge left out whole."""
    lines = []
    for x in dict.fromkeys(k[0] for k in report):
        parts = []
        for (bx, y), r in report.items():
            if bx != x:
                continue
            words = f"{y} {r['turned']} of {r['pairs']} turned back"
            if r["unresolved"]:
                words += f", {r['unresolved']} left out (their turn could not be told: add views " \
                         f"between them, turning the board less than 70 deg from one to the next)"
            if "left_out" in r:
                words += f", the edge left out: {r['left_out']}"
            parts.append(words)
        lines.append(f"turn-symmetric board {x} (it looks the same turned by 180 deg; the pose "
                     f"stream tells which views are turned): " + "; ".join(parts))
    return lines
